"""The experiment runner: validation, seeding independent of workers, resume after a kill, caching,
tables, and the Dask and Ray backends on local two-worker clusters."""
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from tracker.app.compare import compare
from tracker.app.experiment import load_experiment
from tracker.app.report import bootstrap_interval
from tracker.core.errors import InputError

SAMPLE = Path(__file__).resolve().parents[2] / "data_tools" / "samples" / "cmu07"
CLIP = SAMPLE / "07_01.amc"


def write_experiment(folder: Path, priors=("zero-velocity", "constant-velocity"), seeds=2, extra="",
                     tracking="particles = 40\nframes = 5") -> Path:
    text = f'''description = "tiny"
seed = 11
seeds = {seeds}
{extra}
[tracking]
{tracking}

[[sequence]]
name = "walk"
mocap = "{SAMPLE / '07_02.amc'}"
frames = 6
'''
    for p in priors:
        text += f'\n[[prior]]\nname = "{p}"\n'
    path = folder / "exp.toml"
    path.write_text(text)
    return path


def run_numbers(out: Path) -> dict:
    return {json.loads((d / "result.json").read_text())["run"]["key"]:
            json.loads((d / "result.json").read_text())["metrics"] for d in (out / "runs").iterdir()}


@pytest.mark.parametrize("mutation, expected", [
    ("seedz = 3", "unknown key(s) 'seedz'"),
    ('[[prior]]\nname = "zero-velocity"\nlabel = "zero-velocity"', "prior labels must be unique"),
    ('[[prior]]\nname = "crbm"', "needs models = [...] or train = [...]"),
    ('[[prior]]\nname = "crbm"\nmodels = ["missing.pt"]', "file not found"),
    ('[[prior]]\nname = "nope"', "unknown prior 'nope'"),
    ('[[prior]]\nname = "zero-velocity"\nlabel = "z2"\noptions = { gibbs_steps = 3 }', "takes no option"),
    ('[[prior]]\nname = "zero-velocity"\nlabel = "z2"\ntrain_seeds = [0, 1]', "train_seeds repeats the entry's"),
    (f'[[prior]]\nname = "crbm"\ntrain_seeds = [0, 1]\ntrain = [{{ mocap = ["{CLIP}"], seed = 3 }}]',
     "either as train_seeds or as each training's seed"),
    (f'[[prior]]\nname = "crbm"\ntrain_seeds = [1, 1]\ntrain = [{{ mocap = ["{CLIP}"] }}]',
     "train_seeds must be distinct integers"),
    (f'[[prior]]\nname = "crbm"\ntrain_seeds = 3\ntrain = [{{ mocap = ["{CLIP}"] }}]',
     "train_seeds must be a list"),

])
def test_experiment_file_is_validated_whole(tmp_path, mutation, expected):
    path = write_experiment(tmp_path)
    path.write_text(path.read_text() + "\n" + mutation + "\n") if mutation.startswith("[[") else \
        path.write_text(mutation + "\n" + path.read_text())
    with pytest.raises(InputError) as err:
        load_experiment(path)
    assert expected in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize("setting, expected", [
    ('noise = "x"', "synth setting: noise must be a number, got 'x'"),
    ("turn = 400", "synth setting: turn must be at least -360 and at most 360, got 400"),
    ("occluder = 1", "synth setting: occluder must be true or false"),
    ("seed = -1", "synth setting: seed must be at least 0"),
    ('switch_at = "a"', "switch_at: expected an integer"),
    ("missing_camera = 4", "missing_camera 4 is not one of the 4 rendered cameras"),
])
def test_rendering_settings_are_checked_with_the_file(tmp_path, setting, expected):
    path = write_experiment(tmp_path)
    path.write_text(path.read_text().replace("frames = 6\n", f"frames = 6\n{setting}\n"))
    with pytest.raises(InputError) as err:
        load_experiment(path)
    assert expected in str(err.value) and "sequence 'walk'" in str(err.value)
    path.write_text(path.read_text().replace(setting, "turn = 90"))
    assert load_experiment(path).sequences[0].synth["turn"] == 90  # the turn itself is a rendering setting


@pytest.mark.slow
def test_views_out_of_range_and_unfit_model_refused_before_any_run(tmp_path):
    path = write_experiment(tmp_path, tracking="particles = 40\nframes = 5\nviews = [0, 7]")
    with pytest.raises(InputError, match=r"views \[0, 7\] out of range for sequence 'walk'"):
        compare(path, tmp_path / "out", say=lambda s: None, progress=False)
    assert not (tmp_path / "out").exists()  # a refused experiment leaves nothing behind
    import tracker

    model = tracker.train("crbm", [SAMPLE / "07_01.amc"], skeletons=[SAMPLE / "07.asf"], fps=30.0, order=1,
                          epochs=2, hidden=10)
    model.save(tmp_path / "c30.pt")
    path = write_experiment(tmp_path, priors=())
    path.write_text(path.read_text() + f'\n[[prior]]\nname = "crbm"\nmodels = ["{tmp_path / "c30.pt"}"]\n')
    with pytest.raises(InputError, match="prior 'crbm' on sequence 'walk'.*30 fps"):
        compare(path, tmp_path / "out", say=lambda s: None, progress=False)


@pytest.mark.slow
def test_numbers_do_not_depend_on_workers_and_finished_runs_are_skipped(tmp_path):
    path = write_experiment(tmp_path)
    said = []
    compare(path, tmp_path / "a", jobs=1, say=said.append, progress=False)
    compare(path, tmp_path / "b", jobs=2, say=said.append, progress=False)
    assert run_numbers(tmp_path / "a") == run_numbers(tmp_path / "b") and len(run_numbers(tmp_path / "a")) == 4
    said.clear()
    summary = compare(path, tmp_path / "a", jobs=2, say=said.append, progress=False)
    assert any("4 finished before (skipped), 0 to run" in s for s in said)
    assert "zero-velocity" in summary["table"] and "Paired difference" in summary["table"]
    for name in ("table.md", "table.csv", "per_frame.png"):
        assert (tmp_path / "a" / name).stat().st_size > 100
    # Changing one setting reruns only the runs it affects: a third prior adds two runs.
    path = write_experiment(tmp_path, priors=("zero-velocity", "constant-velocity", "gpdm"))
    path.write_text(path.read_text().replace('name = "gpdm"', 'name = "zero-velocity"\nlabel = "zv-scaled"\n'
                                             'options = { prior_scale = 0.5 }'))
    said.clear()
    compare(path, tmp_path / "a", jobs=1, say=said.append, progress=False)
    assert any("6 runs: 4 finished before (skipped), 2 to run" in s for s in said)
    rows = (tmp_path / "a" / "table.csv").read_text()
    assert "zv-scaled" in rows and rows.count("mpjpe_abs") == 3


@pytest.mark.slow
def test_unset_annealing_layers_are_tracks_default_for_every_prior(tmp_path):
    def layers(out):
        return {json.loads((d / "result.json").read_text())["annealing_layers"] for d in (out / "runs").iterdir()}

    path = write_experiment(tmp_path, priors=("zero-velocity",), seeds=1, tracking="particles = 30\nframes = 4")
    compare(path, tmp_path / "a", say=lambda s: None, progress=False)
    assert layers(tmp_path / "a") == {3}
    clips = f'["{CLIP}", "{SAMPLE / "07_02.amc"}"]'
    path.write_text(path.read_text() + f'\n[[prior]]\nname = "fcrbm"\n'
                    f'train = [{{ mocap = {clips}, options = {{ order = 1, labels = "walk,run", epochs = 2, '
                    'hidden = 10, factors = 5, features = 3 } }]\n')
    compare(path, tmp_path / "b", say=lambda s: None, progress=False)  # the FCRBM infers the style: a mixture
    assert layers(tmp_path / "b") == {3}
    path.write_text(path.read_text().replace("particles = 30", "particles = 30\nannealing_layers = []"))
    with pytest.raises(InputError, match=r"annealing_layers: expected a value or a non-empty list"):
        load_experiment(path)


def test_a_train_seeds_group_is_no_baseline_but_its_rows_are(tmp_path):
    path = write_experiment(tmp_path, priors=())
    entry = f'\n[[prior]]\nlabel = "C"\nname = "crbm"\ntrain_seeds = [0, 1]\ntrain = [{{ mocap = ["{CLIP}"] }}]\n'
    path.write_text('baseline = "C"\n' + path.read_text() + entry)
    with pytest.raises(InputError, match="name one of its rows, e.g. 'C, training seed 0'"):
        load_experiment(path)
    path.write_text('baseline = "C, training seed 1"\n' + path.read_text().split("\n", 1)[1])
    assert load_experiment(path).baseline == "C, training seed 1"


@pytest.mark.slow
def test_train_seeds_repeat_a_training_and_the_report_averages_over_the_models(tmp_path):
    path = write_experiment(tmp_path, priors=("zero-velocity",))
    train = f'{{ mocap = ["{CLIP}"], options = {{ order = 1, epochs = 2, hidden = 10 }} }}'
    path.write_text(path.read_text() + f'\n[[prior]]\nlabel = "C"\nname = "crbm"\ntrain_seeds = [4, 7]\n'
                                       f'train = [{train}]\n')
    exp = load_experiment(path)
    assert [(p.label, p.replicate_of, p.training_seed, [t.seed for t in p.train]) for p in exp.priors[1:]] == [
        ("C, training seed 4", "C", 4, [4]), ("C, training seed 7", "C", 7, [7])]
    compare(path, tmp_path / "out", say=lambda s: None, progress=False)
    assert len(list((tmp_path / "out" / "models").iterdir())) == 2  # one model per training seed
    with open(tmp_path / "out" / "table.csv", newline="") as f:
        rows = {r["row"]: (float(r["mean"]), float(r["std"]), int(r["runs"])) for r in csv.DictReader(f)
                if r["metric"] == "mpjpe_abs"}
    one, two = rows["C, training seed 4"][0], rows["C, training seed 7"][0]
    assert one != two  # different models
    mean, between, runs = rows["C (over 2 training seeds)"]
    assert mean == pytest.approx((one + two) / 2, abs=1e-3) and between == pytest.approx(abs(one - two) / 2 ** 0.5,
                                                                                           abs=1e-3) and runs == 4
    assert "## Over training seeds" in (tmp_path / "out" / "table.md").read_text()


@pytest.mark.slow
def test_killed_experiment_resumes_without_redoing_finished_runs(tmp_path):
    path = write_experiment(tmp_path, seeds=4, tracking="particles = 40\nframes = 6")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "tracker", "compare", str(path), "--out", str(out), "--jobs", "1"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline:
        done = [d for d in (out / "runs").glob("*") if not d.name.startswith(".")] if (out / "runs").exists() else []
        if len(done) >= 2:
            break
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    finished = {d.name for d in (out / "runs").glob("*") if not d.name.startswith(".")}
    assert 2 <= len(finished) < 8, finished
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-500:]
    assert f"8 runs: {len(finished)} finished before (skipped), {8 - len(finished)} to run" in r.stderr  # a log line
    after = {d.name for d in (out / "runs").iterdir()}
    assert finished <= after and len(after) == 8  # nothing half-written left, nothing redone


@pytest.mark.slow
def test_bad_command_line_values_exit_2(tmp_path):
    path = write_experiment(tmp_path)
    for args, expected in [(["--jobs", "0"], "must be at least 1"), (["--backend", "spark"], "invalid choice")]:
        r = subprocess.run([sys.executable, "-m", "tracker", "compare", str(path), "--out", str(tmp_path / "o"),
                            *args], capture_output=True, text=True)
        assert r.returncode == 2 and expected in r.stderr and "Traceback" not in r.stderr


def test_bootstrap_interval_covers_the_mean():
    d = np.random.default_rng(0).normal(5.0, 1.0, 20)
    lo, hi = bootstrap_interval(d)
    assert lo < d.mean() < hi and hi - lo < 2.0
    assert bootstrap_interval(d) == bootstrap_interval(d)  # seeded


@pytest.mark.slow
@pytest.mark.optional
@pytest.mark.parametrize("backend", ["dask", "ray"])
def test_cluster_backends_with_two_workers(tmp_path, backend):
    pytest.importorskip("distributed" if backend == "dask" else "ray")
    path = write_experiment(tmp_path)
    compare(path, tmp_path / "local", jobs=1, say=lambda s: None, progress=False)
    compare(path, tmp_path / backend, jobs=2, backend=backend, say=lambda s: None, progress=False)
    assert run_numbers(tmp_path / backend) == run_numbers(tmp_path / "local")
