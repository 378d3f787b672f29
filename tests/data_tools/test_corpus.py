"""A mocap corpus as an input: folders and glob patterns, labels from names or sidecar files, the corpus
listing, and the cache of converted clips."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from data_tools.motion.cache import cached_retarget, clip_key, entry_path
from data_tools.motion.corpus import is_label_source, label_source, survey
from data_tools.motion.load import expand_mocap, load_training_clips
from tests.conftest import SHARED, need_shared
from tracker.app.cli import main
from tracker.core.errors import InputError

SAMPLES = Path(__file__).resolve().parents[2] / "data_tools" / "samples" / "cmu07"
#: Frames kept of each sample walk in the synthetic corpus (short: fast to retarget).
FRAMES = 24


def short_amc(src: Path, out: Path, frames: int = FRAMES) -> Path:
    """The first ``frames`` frames of the AMC ``src`` written to ``out``."""
    lines, count = [], 0
    for line in src.read_text().splitlines():
        if line.strip().isdigit():
            count += 1
            if count > frames:
                break
        lines.append(line)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    return out


@pytest.fixture()
def corpus(tmp_path) -> Path:
    """walks/a/07.asf + 07_01.amc, walks/b/deep/07.asf + 07_02.amc, walks/c/07_bvh_03.bvh, and files that
    are no clips (a README, the ASFs)."""
    from tests.bvh_writer import write_bvh
    from tests.data_tools.test_bvh_conventions import MOTIONBUILDER

    root = tmp_path / "walks"
    for sub, trial in (("a", "07_01"), ("b/deep", "07_02")):
        short_amc(SAMPLES / f"{trial}.amc", root / sub / f"{trial}.amc")
        (root / sub / "07.asf").write_bytes((SAMPLES / "07.asf").read_bytes())
    (root / "c").mkdir()
    write_bvh(root / "c" / "07_bvh_03.bvh", SAMPLES / "07.asf", SAMPLES / "07_01.amc", MOTIONBUILDER,
              frames=FRAMES)
    (root / "README.md").write_text("not a clip\n")
    return root


# -- inputs --------------------------------------------------------------------------------------------------

def test_a_folder_means_its_mocap_files_recursively_in_sorted_order(corpus):
    files = expand_mocap(corpus)
    assert [f.relative_to(corpus).as_posix() for f in files] == [
        "a/07_01.amc", "b/deep/07_02.amc", "c/07_bvh_03.bvh"]


def test_glob_patterns_files_and_duplicates(corpus):
    got = expand_mocap([str(corpus / "**" / "*.amc"), corpus / "a" / "07_01.amc", str(corpus / "c" / "*")])
    assert [f.name for f in got] == ["07_01.amc", "07_02.amc", "07_bvh_03.bvh"]  # 07_01 once; README left out
    assert expand_mocap("*/07_01.amc", base=corpus) == [corpus / "a" / "07_01.amc"]


@pytest.mark.parametrize("item, message", [
    ("missing.amc", "no such file or folder"),
    ("*.bvh", "the pattern matches no mocap file"),
    ("*.md", "the pattern matches 1 path(s) but no mocap file"),
])
def test_inputs_that_name_nothing_are_refused(corpus, item, message):
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        expand_mocap(item, base=corpus)


def test_a_folder_without_mocap_is_refused(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(InputError, match="holds no mocap file"):
        expand_mocap(tmp_path)


# -- labels --------------------------------------------------------------------------------------------------

def test_labels_from_a_name_pattern():
    src = label_source("dataset-2_{content}_{style}_{take}")
    assert src.labels_of("x/dataset-2_walk-left_elderly_001.bvh") == {
        "content": "walk-left", "style": "elderly", "take": "001"}
    with pytest.raises(InputError, match="several keys .*#KEY"):
        src.label_of("dataset-2_walk_elderly_001.bvh")
    assert label_source("dataset-2_{content}_{style}_{take}#style").label_of("d/dataset-2_run_active_002.bvh") \
        == "active"
    assert label_source("dataset-2_{}_{style}_{}").label_of("dataset-2_run_active_002.bvh") == "active"
    assert label_source("dataset-2_{content}_{style}_{}#content,style").training_labels(
        ["dataset-2_run_active_002.bvh", "dataset-2_walk_normal_001.bvh"]) == ["run.active", "walk.normal"]
    with pytest.raises(InputError, match="does not match the labels pattern") as err:
        src.labels_of("07_01.amc")
    assert err.value.path == "07_01.amc"


def test_pattern_with_folders_and_a_repeated_key():
    src = label_source("{subject}/{subject}_{trial}")
    assert src.labels_of("/data/cmu/07/07_01.amc") == {"subject": "07", "trial": "01"}
    with pytest.raises(InputError, match="does not match"):
        src.labels_of("/data/cmu/07/09_01.amc")  # the subject's folder and the file disagree


@pytest.mark.parametrize("text, message", [
    ("a_{content", "unbalanced braces"),
    ("a_{1x}", "is not a key"),
    ("a_{}", "names no key"),
    ("a_{content}#style", "has no key 'style'"),
])
def test_bad_patterns(text, message):
    with pytest.raises(InputError, match=message):
        label_source(text)


def test_is_label_source():
    assert is_label_source("dataset-2_{content}_{style}_{take}#style")
    assert is_label_source("labels.csv#style") and is_label_source("labels.toml")
    assert not is_label_source("walk,walk,run") and not is_label_source(None)


def test_labels_from_sidecar_files(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "labels.csv").write_text("file,style,content\n07_01.amc,normal,walk\nsub/x.bvh,tired,walk\n")
    (tmp_path / "labels.json").write_text(json.dumps({"07_01": "normal", "x.bvh": "tired"}))
    (tmp_path / "labels.toml").write_text('"07_01.amc" = { style = "normal" }\n"sub/x" = { style = "tired" }\n')
    clips = [tmp_path / "07_01.amc", tmp_path / "sub" / "x.bvh"]
    csv_labels = label_source(tmp_path / "labels.csv")
    assert csv_labels.labels_of(clips[0]) == {"style": "normal", "content": "walk"}
    assert label_source(f"{tmp_path / 'labels.csv'}#style").training_labels(clips) == ["normal", "tired"]
    assert label_source(tmp_path / "labels.json").training_labels(clips) == ["normal", "tired"]  # key "label"
    assert label_source(tmp_path / "labels.toml").training_labels(clips) == ["normal", "tired"]
    with pytest.raises(InputError, match="several keys"):
        csv_labels.training_keys()
    for name in ("labels.csv", "labels.json", "labels.toml"):
        with pytest.raises(InputError, match="no labels for this file") as err:
            label_source(tmp_path / name).labels_of(tmp_path / "other.amc")
        assert err.value.path == str(tmp_path / "other.amc")


@pytest.mark.parametrize("name, text, message", [
    ("l.csv", "file\n", "needs a header row"),
    ("l.csv", "file,style\na.amc,no good\n", "is not a label"),
    ("l.csv", "file,style\na.amc,x,y\n", "line 2: 3 column"),
    ("l.json", "{", "not valid JSON"),
    ("l.toml", "[", "not valid TOML"),
    ("l.json", "[]", "maps each file to its labels"),
])
def test_bad_sidecar_files(tmp_path, name, text, message):
    (tmp_path / name).write_text(text)
    with pytest.raises(InputError, match=message) as err:
        label_source(tmp_path / name)
    assert str(tmp_path / name) in str(err.value)


# -- the survey and the corpus command ------------------------------------------------------------------------

def test_survey_lists_every_clip_and_every_refusal(corpus):
    (corpus / "c" / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n")
    short_amc(SAMPLES / "07_01.amc", corpus / "lonely" / "07_01.amc")  # no ASF beside it
    entries = survey(corpus, labels="{}_{trial}")
    by_name = {Path(e.path).relative_to(corpus).as_posix(): e for e in entries}
    assert list(by_name) == ["a/07_01.amc", "b/deep/07_02.amc", "c/07_bvh_03.bvh", "c/broken.bvh",
                             "lonely/07_01.amc"]
    good = by_name["a/07_01.amc"]
    assert (good.frames, good.fps, good.up, good.labels) == (FRAMES, 120.0, "y", {"trial": "01"})
    assert good.naming.startswith("CMU ASF") and "56.44 mm" in good.unit
    assert by_name["c/07_bvh_03.bvh"].labels == {"trial": "bvh_03"}
    assert by_name["c/broken.bvh"].refused and "ASF" in by_name["lonely/07_01.amc"].refused
    assert [e.refused is None for e in entries] == [True, True, True, False, False]


def test_corpus_command_text_and_json(corpus, capsys):
    assert main(["corpus", str(corpus), "--labels", "{}_{trial}"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:4] == ["file", "frames", "Hz", "seconds"]
    assert len(out) == 5 and "trial=01" in out[1]
    assert out[-1] == f"total: 3 clip(s), {3 * FRAMES} frames, 0.0 min (3 at 120 Hz); 0 refused"
    (corpus / "bad.amc").write_text("1\nroot 0 0 0 0 0 0\n")
    assert main(["corpus", str(corpus), "--json"]) == 2
    doc = json.loads(capsys.readouterr().out)
    assert doc["total"] == {"clips": 3, "frames": 3 * FRAMES, "seconds": round(3 * FRAMES / 120, 3),
                            "rates": {"120": 3}, "refused": 1}
    assert doc["refused"][0]["file"].endswith("bad.amc") and doc["refused"][0]["reason"]
    assert doc["clips"][0]["frames"] == FRAMES and doc["clips"][0]["up"] == "y"


def test_corpus_command_refuses_a_missing_path_in_one_line(tmp_path, capsys):
    assert main(["corpus", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such file or folder" in err[0]


@pytest.mark.shared
@pytest.mark.slow
def test_shared_corpus_lists_with_no_refusals(capsys):
    cmu, bandai = need_shared(SHARED / "mocap" / "cmu"), need_shared(SHARED / "mocap" / "bandai2")
    assert main(["corpus", str(cmu), str(bandai), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["refused"] == [] and doc["total"]["clips"] >= 37 + 210
    assert doc["total"]["rates"]["30"] >= 210
    names = {Path(c["file"]).name: c for c in doc["clips"]}
    assert names["07_01.amc"]["frames"] == 316 and names["131_01.bvh"]["frames"] == 994
    entries = survey(str(bandai / "dataset-2_walk_*_001.bvh"), labels="dataset-2_{content}_{style}_{take}")
    assert sorted(e.labels["style"] for e in entries) == [
        "active", "elderly", "exhausted", "feminine", "masculine", "normal", "youthful"]


# -- the cache ----------------------------------------------------------------------------------------------

def test_cache_hit_miss_on_changed_bytes_and_corrupt_entry(corpus, tmp_path):
    cache = tmp_path / "cache"
    amc = corpus / "a" / "07_01.amc"
    first = load_training_clips([amc], fps=60.0, cache=cache)[0]
    entries = list(cache.rglob("*.npz"))
    assert len(entries) == 1

    calls = []
    again = cached_retarget(lambda: calls.append(1), amc, skeleton=corpus / "a" / "07.asf", fps=60.0,
                            reader_module="data_tools.motion.load", folder=cache)
    assert calls == [] and again.source == str(amc)  # a hit: nothing converted
    for name in ("poses", "markers", "model_markers"):
        assert np.array_equal(getattr(again, name), getattr(first, name))
    assert again.model.shape == first.model.shape and again.fps == first.fps == 60.0

    short_amc(SAMPLES / "07_01.amc", amc, FRAMES - 4)  # changed bytes: a new entry
    changed = load_training_clips([amc], fps=60.0, cache=cache)[0]
    assert len(list(cache.rglob("*.npz"))) == 2 and len(changed.poses) < len(first.poses)

    entry = max(cache.rglob("*.npz"), key=os.path.getmtime)
    entry.write_bytes(entry.read_bytes()[:100])  # a corrupt entry is recomputed and replaced
    recomputed = load_training_clips([amc], fps=60.0, cache=cache)[0]
    assert np.array_equal(recomputed.poses, changed.poses)
    assert entry.stat().st_size > 100 and not list(cache.rglob(".*"))  # no temporary file left


def test_cache_key_covers_rate_skeleton_and_joint_map(corpus):
    amc, asf = corpus / "a" / "07_01.amc", corpus / "a" / "07.asf"
    base = clip_key(amc, asf, fps=60.0)
    assert base == clip_key(amc, asf, fps=60.0)
    other_asf = corpus / "a" / "other.asf"
    other_asf.write_bytes(asf.read_bytes() + b"\n")
    assert len({base, clip_key(amc, asf, fps=30.0), clip_key(amc, other_asf, fps=60.0),
                clip_key(amc, asf, {"pelvis": "root"}, fps=60.0), clip_key(amc, asf, mm_per_unit=10.0, fps=60.0),
                clip_key(amc, asf, fps=60.0, reader_module="tests.bvh_writer")}) == 6
    assert entry_path(Path("/c"), base) == Path("/c/clips") / base[:2] / f"{base}.npz"


def test_the_api_loads_through_the_cache(corpus, tmp_path, monkeypatch):
    import tracker

    monkeypatch.setenv("POSE_TRACKER_CACHE", str(tmp_path / "env-cache"))
    one = tracker.load_clip(corpus / "c" / "07_bvh_03.bvh", fps=None)
    assert len(list((tmp_path / "env-cache").rglob("*.npz"))) == 1
    clips = tracker.load_clips(str(corpus / "**" / "07_*"), fps=None, cache=tmp_path / "given")
    assert [Path(c.source).name for c in clips] == ["07_01.amc", "07_02.amc", "07_bvh_03.bvh"]
    assert np.array_equal(clips[2].poses, one.poses) and len(list((tmp_path / "given").rglob("*.npz"))) == 3
    monkeypatch.setenv("POSE_TRACKER_CACHE", "off")
    tracker.load_clip(corpus / "c" / "07_bvh_03.bvh", fps=30.0)
    assert len(list((tmp_path / "env-cache").rglob("*.npz"))) == 1


# -- training on a corpus -----------------------------------------------------------------------------------

def test_train_on_a_glob_with_labels_from_the_names(corpus, tmp_path):
    import tracker

    model = tracker.train("fcrbm", str(corpus / "**" / "07_0*.amc"), labels="{}_{trial}", epochs=1,
                          hidden=8, factors=4, features=2, grow_from="none", order=1)
    assert model.labels == ["01", "02"]
    with pytest.raises(InputError, match="several keys"):
        tracker.train("fcrbm", str(corpus), labels="{subject}_{trial}", epochs=1)
    with pytest.raises(InputError, match="does not match the labels pattern"):
        tracker.train("fcrbm", str(corpus), labels="{s}_{t}_{u}#t", epochs=1, grow_from="none", order=1)


def test_train_command_on_a_folder(corpus, tmp_path, capsys):
    out = tmp_path / "crbm.pt"
    assert main(["train", "--prior", "crbm", "--mocap", str(corpus / "a"), str(corpus / "b"), "--order", "1",
                 "--epochs", "1", "--hidden", "8", "--grow-from", "none", "--out", str(out)]) == 0
    assert out.is_file()
    assert main(["train", "--prior", "fcrbm", "--mocap", str(corpus), "--labels", "{a}_{b}", "--epochs", "1",
                 "--out", str(tmp_path / "f.pt")]) == 2
    assert "several keys" in capsys.readouterr().err
    labels = tmp_path / "styles.csv"
    labels.write_text("file,style\n07_01,normal\n07_02,tired\n07_bvh_03,normal\n")
    assert main(["train", "--prior", "fcrbm", "--mocap", str(corpus / "**" / "07_0?.amc"), str(corpus / "c"),
                 "--labels", str(labels), "--epochs", "1", "--hidden", "8", "--factors", "4", "--features", "2",
                 "--order", "1", "--grow-from", "none", "--out", str(tmp_path / "f.pt")]) == 0
    assert "labels normal, tired" in capsys.readouterr().out


def test_experiment_train_entries_take_folders_and_patterns(corpus, tmp_path):
    from tracker.app.experiment import load_experiment

    (tmp_path / "exp.toml").write_text(f'''
[[sequence]]
name = "walk"
mocap = "{corpus / 'a' / '07_01.amc'}"
[[prior]]
name = "crbm"
train = {{ mocap = ["{corpus}", {{ path = "{corpus / '**' / '*.amc'}", start = 2 }}] }}
train_mocap = ["{corpus / 'b'}"]
''')
    exp = load_experiment(tmp_path / "exp.toml")
    clips = exp.priors[0].train[0].mocap
    assert [c.path.name for c in clips] == ["07_01.amc", "07_02.amc", "07_bvh_03.bvh", "07_01.amc", "07_02.amc"]
    assert [c.start for c in clips] == [0, 0, 0, 2, 2]
    assert [c.path.name for c in exp.priors[0].train_mocap] == ["07_02.amc"]
    (tmp_path / "bad.toml").write_text(f'[[sequence]]\nname = "w"\nmocap = "{corpus / "a" / "07_01.amc"}"\n'
                                       f'[[prior]]\nname = "crbm"\ntrain = {{ mocap = ["{corpus}/*.c3d"] }}\n')
    refusal = r"prior 'crbm' train 1: the pattern matches no mocap file \(.amc, .bvh\): .*\*\.c3d$"
    with pytest.raises(InputError, match=refusal):
        load_experiment(tmp_path / "bad.toml")


def test_experiment_labels_are_read_from_names_or_a_sidecar_as_the_file_loads(corpus, tmp_path):
    from tracker.app.experiment import load_experiment

    def experiment(labels: str) -> Path:
        path = tmp_path / "fcrbm.toml"
        path.write_text(f'[[sequence]]\nname = "w"\nmocap = "{corpus / "a" / "07_01.amc"}"\n[[prior]]\n'
                        f'name = "fcrbm"\ntrain = {{ mocap = ["{corpus / "**" / "*.amc"}"], '
                        f'options = {{ labels = "{labels}" }} }}\n')
        return path

    assert load_experiment(experiment("{}_{trial}")).priors[0].train[0].options["labels"] == "01,02"
    (tmp_path / "styles.csv").write_text("file,style\n07_01,normal\n07_02,tired\n")
    spec = load_experiment(experiment("styles.csv#style")).priors[0].train[0]  # beside the experiment file
    assert spec.options["labels"] == "normal,tired"
    (tmp_path / "styles.csv").write_text("file,style\n07_01,normal\n")
    with pytest.raises(InputError, match=r"fcrbm.toml: prior 'fcrbm' train 1: .*07_02.amc: no labels"):
        load_experiment(experiment("styles.csv#style"))


@pytest.mark.slow
def test_the_retarget_version_covers_every_module_a_conversion_runs(corpus):
    """Reading and retargeting an AMC and a BVH (the cache off) import no module of the package that the cache
    key's digest leaves out: a new one would convert differently without making new entries."""
    import subprocess
    import sys

    from data_tools.motion.cache import CONVERSION_MODULES

    code = ("import sys; from data_tools.motion.load import load_training_clips; "
            f"load_training_clips([{str(corpus / 'a' / '07_01.amc')!r}, {str(corpus / 'c' / '07_bvh_03.bvh')!r}],"
            " fps=30.0, cache=None); "
            "print(' '.join(m for m in sys.modules if m.split('.')[0] in ('data_tools', 'tracker', 'priors', "
            "'likelihoods')))")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    loaded = set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                                check=True).stdout.split())
    assert "data_tools.motion.retarget" in loaded and "data_tools.motion.bvh" in loaded
    # the cache itself, and the table of readers (the engine's registry, and the camera type it names): no numbers
    cache = {"data_tools.motion.cache", "data_tools.io.files", "data_tools.io.fingerprints"}
    table = {"tracker.engine.registry", "tracker.core.cameras"}
    packages = {"data_tools", "data_tools.io", "data_tools.motion", "tracker", "tracker.core", "tracker.engine"}
    assert loaded - set(CONVERSION_MODULES) - cache - table == packages
