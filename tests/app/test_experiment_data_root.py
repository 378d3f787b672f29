"""An experiment file's data root: its data paths are relative to it, ``compare --data-root`` and the environment
variable POSE_TRACKER_DATA_ROOT replace it, a missing root is one line, and moving the root changes no run's hash."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tracker.app.compare import compare
from tracker.app.experiment import DATA_ROOT_ENV, load_experiment
from tracker.core.errors import InputError

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "data_tools" / "samples"


def write_experiment(folder: Path, data_root: str) -> Path:
    """A tiny experiment whose data paths (a rendered walk cross-faded into another, and a CRBM's training clip)
    are relative to ``data_root``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "exp.toml"
    path.write_text(f'''description = "tiny"
data_root = "{data_root}"
seed = 5
seeds = 1

[tracking]
particles = 30
frames = 4
annealing_layers = 1
views = [0]

[[sequence]]
name = "walk then walk"
mocap = "cmu07/07_02.amc"
then = "cmu07/07_01.amc"
switch_at = 3
fade = 1
frames = 6

[[prior]]
name = "zero-velocity"
train_mocap = ["cmu07/07_01.amc"]
''')
    return path


def copy_of_samples(root: Path) -> Path:
    shutil.copytree(SAMPLES / "cmu07", root / "cmu07")
    return root


def test_data_paths_are_relative_to_the_declared_root(tmp_path):
    path = write_experiment(tmp_path / "exp", "../data")
    copy_of_samples(tmp_path / "data")
    exp = load_experiment(path)
    assert exp.data_root == (tmp_path / "data").resolve()
    assert exp.sequences[0].mocap == (tmp_path / "data" / "cmu07" / "07_02.amc").resolve()
    assert Path(exp.sequences[0].synth["then"]) == (tmp_path / "data" / "cmu07" / "07_01.amc").resolve()
    assert exp.priors[0].train_mocap[0].path == (tmp_path / "data" / "cmu07" / "07_01.amc").resolve()


@pytest.mark.slow
def test_a_copied_file_runs_with_data_root_and_its_runs_keep_their_hashes(tmp_path, monkeypatch):
    monkeypatch.delenv(DATA_ROOT_ENV, raising=False)
    first = write_experiment(tmp_path / "a", "../data")
    copy_of_samples(tmp_path / "data")
    out = tmp_path / "out"
    compare(first, out, say=lambda _: None, progress=False)
    keys = sorted(p.name for p in (out / "runs").iterdir())
    assert len(keys) == 1
    # the same file copied elsewhere, its declared root wrong there, and the data moved: --data-root finds it
    moved = tmp_path / "moved_data"
    shutil.move(tmp_path / "data", moved)
    copy = write_experiment(tmp_path / "elsewhere" / "deeper", "../no_such_folder")
    said = []
    compare(copy, out, say=said.append, progress=False, data_root=moved)
    assert sorted(p.name for p in (out / "runs").iterdir()) == keys  # no new run: the hash holds no path
    assert any("1 finished before (skipped), 0 to run" in line for line in said), said
    assert json.loads((out / "experiment.json").read_text())["data_root"] == str(moved.resolve())


def test_the_environment_variable_replaces_the_declared_root(tmp_path, monkeypatch):
    path = write_experiment(tmp_path / "exp", "../no_such_folder")
    root = copy_of_samples(tmp_path / "data")
    monkeypatch.setenv(DATA_ROOT_ENV, str(root))
    assert load_experiment(path).sequences[0].mocap == (root / "cmu07" / "07_02.amc").resolve()
    # the explicit argument wins over the environment
    other = copy_of_samples(tmp_path / "other")
    assert load_experiment(path, data_root=other).data_root == other.resolve()


def test_a_file_without_data_root_ignores_the_environment_and_refuses_the_option(tmp_path, monkeypatch):
    folder = tmp_path / "exp"
    copy_of_samples(folder)
    path = write_experiment(folder, "unused")
    path.write_text(path.read_text().replace('data_root = "unused"\n', ""))
    monkeypatch.setenv(DATA_ROOT_ENV, str(tmp_path / "no_such_folder"))
    assert load_experiment(path).data_root is None  # paths relative to the file, as before
    with pytest.raises(InputError, match="declares no data_root"):
        load_experiment(path, data_root=tmp_path)


def test_models_stay_relative_to_the_file(tmp_path):
    path = write_experiment(tmp_path / "exp", "../data")
    copy_of_samples(tmp_path / "data")
    (tmp_path / "exp" / "m.pt").write_bytes(b"only its place is checked here")
    path.write_text(path.read_text() + '\n[[prior]]\nname = "crbm"\nmodels = ["m.pt"]\n')
    assert load_experiment(path).priors[1].models == ((tmp_path / "exp" / "m.pt").resolve(),)


@pytest.mark.parametrize("how", ["file", "option", "env"])
def test_a_missing_data_root_is_one_line_naming_the_file_and_the_path(tmp_path, how):
    path = write_experiment(tmp_path / "exp", "../no_such_folder")
    missing = tmp_path / "elsewhere"
    cmd = [sys.executable, "-m", "tracker", "compare", str(path), "--out", str(tmp_path / "out")]
    env = {k: v for k, v in os.environ.items() if k != DATA_ROOT_ENV}
    if how == "option":
        cmd += ["--data-root", str(missing)]
    elif how == "env":
        env[DATA_ROOT_ENV] = str(missing)
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=REPO, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert str(path) in lines[0] and "data root not found" in lines[0]
    assert str(missing if how != "file" else tmp_path / "exp" / "../no_such_folder") in lines[0]
    assert not (tmp_path / "out").exists()


def test_shipped_experiment_files_name_their_data_through_the_data_root():
    """No shipped file repeats the path to the shared data: each says it once, as its data_root."""
    for path in sorted((REPO / "benchmarks" / "experiments").rglob("*.toml")):
        for line in path.read_text().splitlines():
            if "../" in line:
                assert line.startswith("data_root = "), f"{path}: {line}"
