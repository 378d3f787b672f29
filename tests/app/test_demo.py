"""The demo's parts that need no rendering: the shipped samples it reads, that the pretrained model never saw the
person it tracks, and its line saying what the comparison shows (the whole demo runs in tests/app/test_cli.py and
tests/app/test_overwrite.py)."""
import pytest

from data_tools.motion.asf_amc import read_amc, read_asf
from data_tools.motion.cmu_trials import SKELETON_LENGTHS, TRIAL_FRAMES
from data_tools.samples import CMU_ATTRIBUTION, sample_walks
from tracker.app.demo import TRACK_SUBJECT, comparison_line


def test_the_demo_tracks_a_person_the_pretrained_model_never_saw():
    from priors.neural.file import load_neural
    from priors.pretrained import mixture_model

    asf, walks = sample_walks(TRACK_SUBJECT)
    assert [w.name for w in walks] == ["07_01.amc", "07_02.amc"]
    sources = load_neural(mixture_model()).sources
    assert len(sources) == 31 and all(s.startswith("cmu/") for s in sources)  # CMU trials only
    assert not [s for s in sources if "/07/" in s or "07_" in s.split("/")[-1]]  # no clip of subject 7
    assert sample_walks() == (asf, walks)  # the default stays subject 7, as the API's users expect


def test_the_shipped_subject_2_walk_is_whole_and_attributed():
    asf, (walk,) = sample_walks(2)
    skeleton = read_asf(asf)  # the trial as CMU's database has it, whole: what `fetch` checks a download against
    assert sum(b.length for b in skeleton.bones.values()) == pytest.approx(SKELETON_LENGTHS["02"], abs=1e-4)
    assert len(read_amc(walk, skeleton)["root"]) == TRIAL_FRAMES["02_01"] == 343  # 2.9 s at 120 Hz
    attribution = (asf.parent / "ATTRIBUTION.md").read_text()
    assert all(sentence in " ".join(attribution.split()) for sentence in CMU_ATTRIBUTION.split(". "))


def test_sample_walks_names_the_shipped_subjects():
    with pytest.raises(ValueError, match="no shipped walks of CMU subject 16; the shipped subjects are 7, 2"):
        sample_walks(16)


def test_the_comparison_line_says_which_prior_won_and_by_what_ratio():
    line = comparison_line({"zero-velocity": [116.2, 58.3, 60.2], "mixture": [40.7, 35.7, 30.7]},
                           "CMU subject 7's walk 07_01")
    assert "\n" not in line
    assert line == ("What this shows: on CMU subject 7's walk 07_01, a person the pretrained model never saw, the "
                    "mixture of the pretrained neural prior and zero-velocity tracked best over 3 seeds: the mixture "
                    "35.7 mm (seeds: 40.7, 35.7, 30.7), 2.19 times lower than zero-velocity's 78.2 mm (seeds: "
                    "116.2, 58.3, 60.2); one short clip: a sketch, not a benchmark.")


def test_the_comparison_line_says_so_when_zero_velocity_wins():
    line = comparison_line({"zero-velocity": [31.0, 30.0, 32.0], "mixture": [33.0, 31.0, 32.0]}, "someone")
    assert "zero-velocity tracked best over 3 seeds" in line
    assert "the mixture 32.0 mm (seeds: 33.0, 31.0, 32.0), 1.03 times higher than zero-velocity's 31.0 mm" in line
