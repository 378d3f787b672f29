"""The demo's parts that need no rendering: the shipped samples it reads and its line saying what the
comparison shows (the whole demo runs in tests/test_cli.py and tests/test_overwrite.py)."""
import pytest

from data_tools.asf_amc import read_amc, read_asf
from data_tools.cmu_trials import SKELETON_LENGTHS, TRIAL_FRAMES
from data_tools.samples import CMU_ATTRIBUTION, sample_walks
from tracker.app.demo import TRACK_SUBJECT, TRAIN_SUBJECT, comparison_line


def test_the_demo_tracks_a_person_its_prior_never_saw():
    train_asf, train_walks = sample_walks(TRAIN_SUBJECT)
    track_asf, track_walks = sample_walks(TRACK_SUBJECT)
    assert train_asf != track_asf and not set(train_walks) & set(track_walks)
    assert [w.name for w in train_walks] == ["07_01.amc", "07_02.amc"]
    assert [w.name for w in track_walks] == ["02_01.amc"]
    assert sample_walks() == (train_asf, train_walks)  # the default stays subject 7, as the API's users expect


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
    line = comparison_line({"zero-velocity": 45.9, "crbm": 38.5, "mixture": 37.5}, "CMU subject 2",
                           "subject 7's walks")
    assert "\n" not in line
    assert line.startswith("What this shows: on CMU subject 2, a person the CRBM never saw (it learned from "
                           "subject 7's walks), the mixture tracked best; against zero-velocity's 45.9 mm: "
                           "the CRBM 38.5 mm (1.19 times lower), the mixture 37.5 mm (1.22 times lower)")


def test_the_comparison_line_says_so_when_zero_velocity_wins():
    line = comparison_line({"zero-velocity": 31.0, "crbm": 40.1, "mixture": 31.04}, "CMU subject 16", "others")
    assert "zero-velocity tracked best" in line
    assert "the CRBM 40.1 mm (1.29 times higher), the mixture 31.0 mm (the same)" in line
