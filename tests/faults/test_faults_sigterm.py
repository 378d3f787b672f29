"""SIGTERM (``kill``, ``docker stop``, a cluster's preemption) stops ``track``, ``train`` and ``compare`` as Ctrl-C
does: what can be resumed is kept, one line names the command that continues, exit status 143; and the continued
run gives the numbers of an uninterrupted one, whenever the signal came (before the first frame, before the first
checkpoint, in the middle). A run killed outright (SIGKILL) before its first checkpoint continues too."""
from __future__ import annotations

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
import torch

from data_tools.samples import sample_walks
from tests.faults.test_bad_input_readers import tiny_sequence
from tests.faults.test_faults_disk import run_cli, track_args
from tracker.app import api, cli
from tracker.app.run_folder import REQUEST_FILE

ASF, WALKS = sample_walks()
REPO = Path(__file__).resolve().parents[2]


def sigterm() -> None:
    """SIGTERM to this process; its handler (set by the command line) raises in the main thread at once."""
    os.kill(os.getpid(), signal.SIGTERM)
    for _ in range(200):  # the handler runs between two bytecodes: well before this ends
        time.sleep(0.005)
    raise AssertionError("SIGTERM was not answered")


def one_warning(err: str, *fragments: str) -> str:
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.strip()]
    assert lines and "warning: interrupted" in lines[-1] and "Traceback" not in err, err[-2000:]
    assert sum("interrupted" in line for line in lines) == 1, err[-2000:]
    for f in fragments:
        assert f in lines[-1], (f, lines[-1])
    return lines[-1]


@pytest.fixture(autouse=True)
def quick_random_walk_scale():
    """The random-walk priors' scale, fixed (the default retargets the shipped walks, seconds per run): what is
    tested here is how a run stops and continues, not its prior. (Its own patcher: the tests undo theirs.)"""
    import tracker.app.api as api

    patch = pytest.MonkeyPatch()
    patch.setattr(api, "random_walk_scale", lambda seq, train_mocap=None: np.full(seq.model.n_dofs, 0.02))
    yield
    patch.undo()


@pytest.fixture
def seq(tmp_path):
    return tiny_sequence(tmp_path / "seq", frames=8)


def poses(out: Path) -> np.ndarray:
    with np.load(out / "estimates.npz") as f:
        return f["poses"]


# -- track ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("moment", ["before the first frame", "before the first checkpoint", "in the middle"])
def test_track_stopped_by_sigterm_resumes_to_the_uninterrupted_result(moment, seq, tmp_path, capsys, monkeypatch):
    argv = track_args(seq, tmp_path / "cut", "--checkpoint-every", "3", "--seed", "4")
    assert run_cli(track_args(seq, tmp_path / "whole", "--seed", "4"), capsys)[0] == 0
    real = api.track
    at = {"before the first frame": 0, "before the first checkpoint": 2, "in the middle": 4}[moment]

    def track(*args, on_frame=None, **kwargs):
        if at == 0:
            sigterm()

        def frame(step, err):
            on_frame(step, err)
            if step.frame == at + 1:  # the frames tracked so far: 2 .. at+1
                sigterm()
        return real(*args, on_frame=frame, **kwargs)

    monkeypatch.setattr(api, "track", track)
    code, err = run_cli(argv, capsys)
    monkeypatch.undo()
    out = tmp_path / "cut"
    assert code == 143
    if at == 0:  # nothing was tracked: nothing stays, and the same command runs it
        one_warning(err, "before the first frame", "run the same command again")
        assert not out.exists()
        assert run_cli(argv, capsys)[0] == 0
    else:
        # the frame being reported when the signal came is not kept: the resumed run tracks it again
        one_warning(err, f"after {at - 1} frame(s)", f"resume with: pose-tracker track --resume {out}")
        partial = json.loads((out / "result.json").read_text())
        assert partial["complete"] is False and partial["frames_tracked"] == at - 1
        assert (out / "checkpoint.npz").exists()  # written at the signal, as Ctrl-C writes it
        assert run_cli(["track", "--resume", str(out)], capsys)[0] == 0
    assert np.array_equal(poses(out), poses(tmp_path / "whole"))
    result = json.loads((out / "result.json").read_text())
    assert result["complete"] is True
    assert result["metrics"] == json.loads((tmp_path / "whole" / "result.json").read_text())["metrics"]


def test_a_run_killed_before_its_first_checkpoint_continues_from_frame_0(seq, tmp_path, capsys, monkeypatch):
    """Killed (SIGKILL: nothing answers it) once its arguments were saved and before any checkpoint: ``--resume``
    tracks from frame 0 with the saved arguments, and the same command again continues the run likewise."""
    argv = track_args(seq, tmp_path / "cut", "--checkpoint-every", "0", "--seed", "4")
    assert run_cli(track_args(seq, tmp_path / "whole", "--seed", "4"), capsys)[0] == 0

    def killed(*args, **kwargs):  # what a SIGKILL leaves: the saved arguments, the cached hashes, no checkpoint
        raise SystemExit(137)

    monkeypatch.setattr(api, "track", killed)
    with pytest.raises(SystemExit):
        cli.main(argv)
    monkeypatch.undo()
    out = tmp_path / "cut"
    assert (out / REQUEST_FILE).exists() and not (out / "checkpoint.npz").exists()
    code, err = run_cli(["track", "--resume", str(out)], capsys)
    assert code == 0 and "tracking from the first frame" in err, err
    assert np.array_equal(poses(out), poses(tmp_path / "whole"))

    again = tmp_path / "again"
    with pytest.raises(SystemExit):
        monkeypatch.setattr(api, "track", killed)
        cli.main(track_args(seq, again, "--checkpoint-every", "0", "--seed", "4"))
    monkeypatch.undo()
    code, err = run_cli(track_args(seq, again, "--checkpoint-every", "0", "--seed", "4"), capsys)
    assert code == 0 and "holds this run, unfinished: continuing it" in err, err
    assert np.array_equal(poses(again), poses(tmp_path / "whole"))
    assert not (again / REQUEST_FILE).exists()


@pytest.mark.parametrize("command, says", [("track", "a run stopped before its first checkpoint starts from its "
                                                       "first frame"),
                                           ("train", "a training stopped before its first checkpoint starts from "
                                                     "the beginning")])
def test_the_help_of_resume_says_what_a_run_without_a_checkpoint_does(command, says):
    """``--resume`` of a run stopped before its first checkpoint starts it again rather than refusing: the help
    says so."""
    from tracker.app.parser import build_parser

    sub = next(a for a in build_parser()._actions if a.choices and command in a.choices).choices[command]
    resume = next(a for a in sub._actions if "--resume" in a.option_strings)
    assert says in " ".join(resume.help.split()), resume.help


def test_another_command_into_an_unfinished_run_is_refused_in_one_line(seq, tmp_path, capsys, monkeypatch):
    out = tmp_path / "cut"
    monkeypatch.setattr(api, "track", lambda *a, **k: (_ for _ in ()).throw(SystemExit(137)))
    with pytest.raises(SystemExit):
        cli.main(track_args(seq, out, "--seed", "4"))
    monkeypatch.undo()
    code, err = run_cli(track_args(seq, out, "--seed", "5"), capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "unfinished run of other arguments (seed)" in lines[0], err
    assert f"pose-tracker track --resume {out}" in lines[0] and "--overwrite" in lines[0]
    assert run_cli(track_args(seq, out, "--seed", "5", "--overwrite"), capsys)[0] == 0


@pytest.mark.slow
def test_a_real_sigterm_to_track_keeps_a_checkpoint_and_exits_143(seq, tmp_path):
    """The signal from outside, as ``kill`` sends it, while the filter runs."""
    out = tmp_path / "cut"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    args = [sys.executable, "-m", "tracker", "--threads", "1", "track", str(seq), "--prior", "zero-velocity",
            "--particles", "3000", "--annealing-layers", "3", "--seed", "4", "--checkpoint-every", "1"]
    proc = subprocess.Popen([*args, "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env)
    deadline = time.time() + 120
    while not (out / "checkpoint.npz").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-1000:]
    one_warning(err, f"resume with: pose-tracker track --resume {out}")
    assert json.loads((out / "result.json").read_text())["complete"] is False
    r = subprocess.run([*args[:3], "track", "--resume", str(out)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-1000:]
    whole = tmp_path / "whole"
    assert subprocess.run([*args, "--out", str(whole)], capture_output=True, env=env).returncode == 0
    assert np.array_equal(poses(out), poses(whole))


# -- train ------------------------------------------------------------------------------------------------------

def model_tensors(path: Path) -> dict[str, torch.Tensor]:
    """Every tensor of a model file (weights, latent points, scales, ...), by its place in the file."""
    out = {}

    def walk(value, where: str) -> None:
        if isinstance(value, torch.Tensor):
            out[where] = value
        elif isinstance(value, dict):
            for key, item in value.items():
                walk(item, f"{where}/{key}")
        elif isinstance(value, (list, tuple)):
            for k, item in enumerate(value):
                walk(item, f"{where}/{k}")
    walk(torch.load(path, weights_only=True), "")
    assert out, f"no tensors in {path}"
    return out


#: Small trainings of the resumable priors, each with the field of its checkpoint's training state that counts
#: what was done (epochs, iterations).
TRAINING = {
    "crbm": (["train", "--prior", "crbm", "--mocap", str(WALKS[0]), "--order", "1", "--epochs", "6", "--hidden", "8"],
             "epoch"),
    "gpdm": (["train", "--prior", "gpdm", "--mocap", str(WALKS[0]), "--iterations", "40", "--latent-dim", "2"],
             "done"),
    "fcrbm": (["train", "--prior", "fcrbm", "--mocap", str(WALKS[0]), "--labels", "walk", "--order", "1", "--epochs",
               "6", "--hidden", "8", "--factors", "4", "--features", "2"], "epoch"),
    "deep-crbm": (["train", "--prior", "deep-crbm", "--mocap", str(WALKS[0]), "--order", "1", "--epochs", "3",
                   "--hidden", "8", "--top-order", "1", "--top-hidden", "4", "--top-epochs", "3"], "epoch"),
}


@pytest.fixture(scope="module")
def whole_models(tmp_path_factory):
    """The model file's tensors of each uninterrupted training of :data:`TRAINING`, trained on first use."""
    cache = {}

    def get(prior: str) -> dict[str, torch.Tensor]:
        if prior not in cache:
            path = tmp_path_factory.mktemp("whole") / f"{prior}.pt"
            assert cli.main(["-q", *TRAINING[prior][0], "--out", str(path)]) == 0
            cache[prior] = model_tensors(path)
        return cache[prior]
    return get


@pytest.mark.slow
@pytest.mark.parametrize("prior, every, at, kept", [
    ("crbm", "3", 0, None),  # before the first epoch: nothing to keep
    ("crbm", "3", 2, 1),     # before the first periodic checkpoint: the state after epoch 1
    ("crbm", "3", 5, 4),     # in the middle, after a periodic checkpoint: the state at the stop, not the periodic one
    ("crbm", None, 4, 3),    # without periodic checkpoints
    ("gpdm", None, 0, None),
    ("gpdm", "20", 10, 10),  # the progress of a chunk is reported once its state is kept
    ("gpdm", "20", 30, 30),
    ("fcrbm", "3", 5, 4),
    ("deep-crbm", None, 5, 1),  # in the second layer, two epochs after the first layer's three
], ids=lambda v: str(v))
def test_train_stopped_by_sigterm_resumes_to_the_uninterrupted_model(prior, every, at, kept, whole_models, tmp_path,
                                                                      capsys, monkeypatch):
    """Stopped at ``at`` epochs (iterations) done, ``train`` keeps the training state after the last finished one
    (``kept``), with or without ``--checkpoint-every``, and ``--resume`` continues from there to the model file of
    an uninterrupted training, bit for bit."""
    from priors.common import read_model_file

    base, counter = TRAINING[prior]
    argv = [*base, *(["--checkpoint-every", every] if every else []), "--out", str(tmp_path / "cut.pt")]
    real = api.train

    def train(*args, progress=None, **kwargs):
        if at == 0:
            sigterm()

        def report(done, total, metrics):
            progress(done, total, metrics)
            if done == at:
                sigterm()
        return real(*args, progress=report, **kwargs)

    monkeypatch.setattr(api, "train", train)
    code, err = run_cli(argv, capsys)
    monkeypatch.undo()
    assert code == 143 and not (tmp_path / "cut.pt").exists()
    checkpoint = tmp_path / "cut.pt.checkpoint"
    if kept is not None:
        one_warning(err, f"continue with: pose-tracker {' '.join(argv)} --resume")
        doc = read_model_file(checkpoint, torch.load(checkpoint, weights_only=True)["format"], "checkpoint")
        assert doc["training_state"][counter] == kept
    else:
        one_warning(err)
        assert "nothing" in err and not checkpoint.exists()
        assert not Path(f"{checkpoint}.inputs.json").exists()  # nothing stays behind
    code, err = run_cli([*argv, "--resume"], capsys)
    assert code == 0, err
    assert (kept is None) == ("training from the start" in err), err
    whole, cut = whole_models(prior), model_tensors(tmp_path / "cut.pt")
    assert sorted(whole) == sorted(cut) and all(torch.equal(whole[k], cut[k]) for k in whole)
    assert not checkpoint.exists()


# -- compare ----------------------------------------------------------------------------------------------------

def table_numbers(out: Path) -> list[dict]:
    with open(out / "table.csv", newline="") as f:
        return [{k: v for k, v in row.items() if "second" not in k} for row in csv.DictReader(f)]


@pytest.fixture
def experiment(tmp_path_factory, quick_random_walk_scale):
    """A tiny experiment (two runs) and its uninterrupted tables."""
    folder = tmp_path_factory.mktemp("experiment")
    seq = tiny_sequence(folder / "seq", frames=6)
    path = folder / "exp.toml"
    path.write_text(f'seed = 11\nseeds = 1\n[tracking]\nparticles = 20\nannealing_layers = 1\n'
                    f'[[sequence]]\nname = "walk"\npath = "{seq}"\n'
                    '[[prior]]\nname = "zero-velocity"\n[[prior]]\nname = "constant-velocity"\n')
    assert cli.main(["-q", "compare", str(path), "--no-videos", "--out", str(folder / "whole")]) == 0
    return path, table_numbers(folder / "whole")


@pytest.mark.parametrize("moment", ["while preparing", "in the first run", "between runs"])
def test_compare_stopped_by_sigterm_continues_to_the_uninterrupted_tables(moment, experiment, tmp_path, capsys,
                                                                          monkeypatch):
    import tracker.app.api as api
    import tracker.app.compare as comparing

    argv = ["compare", str(experiment[0]), "--no-videos", "--out"]
    if moment == "while preparing":
        real_scales = comparing.prepare_scales

        def scales(exp):
            sigterm()
            return real_scales(exp)
        monkeypatch.setattr(comparing, "prepare_scales", scales)
    elif moment == "in the first run":
        real_track = api.track

        def track(*args, on_frame=None, **kwargs):
            def frame(step, err):
                on_frame(step, err)
                if step.frame == 3:
                    sigterm()
            return real_track(*args, on_frame=frame, **kwargs)
        monkeypatch.setattr(api, "track", track)
    else:
        real_run = comparing.execute_run

        def execute(spec):
            summary = real_run(spec)
            sigterm()
            return summary
        monkeypatch.setattr(comparing, "execute_run", execute)
    out = tmp_path / "cut"
    code, err = run_cli([*argv, str(out)], capsys)
    monkeypatch.undo()
    finished = 1 if moment == "between runs" else 0
    assert code == 143
    line = one_warning(err, f"continue with: pose-tracker {' '.join([*argv, str(out)])}")
    assert ("nothing run yet" in line) if moment == "while preparing" else (f"{finished} of 2 runs" in line), line
    assert not list((out / "runs").glob(".*.tmp-*"))  # the unfinished run's folder is removed
    assert json.loads((out / "experiment.json").read_text())["complete"] is False
    code, err = run_cli([*argv, str(out)], capsys)
    assert code == 0 and f"{finished} finished before (skipped)" in err, err
    assert table_numbers(out) == experiment[1]
    assert json.loads((out / "experiment.json").read_text())["complete"] is True


def test_a_run_whose_mixture_component_names_its_model_resumes_from_another_folder(seq, tmp_path, capsys,
                                                                                   monkeypatch):
    """``--components crbm:model=FILE``: the file is saved as an absolute path, as ``--model`` is, so that
    ``--resume`` finds it from any folder."""
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "c.pt").write_bytes((REPO / "tests" / "data" / "crbm3_paced_v0.13.pt").read_bytes())
    monkeypatch.chdir(tmp_path / "models")
    out = tmp_path / "cut"
    argv = ["track", str(seq), "--prior", "mixture", "--components", "crbm:model=c.pt,zero-velocity",
            "--particles", "20", "--annealing-layers", "1", "--checkpoint-every", "0", "--out", str(out)]
    monkeypatch.setattr(api, "track", lambda *a, **k: (_ for _ in ()).throw(SystemExit(137)))
    with pytest.raises(SystemExit):
        cli.main(argv)
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path / "seq")
    code, err = run_cli(["track", "--resume", str(out)], capsys)
    assert code == 0, err
    model = str(tmp_path / "models" / "c.pt")
    assert json.loads((out / "result.json").read_text())["prior_models"] == [model]


@pytest.mark.parametrize("directory", [False, True])
@pytest.mark.parametrize("moment", ["making it", "just made", "writing it", "renaming it"])
def test_a_stop_at_any_moment_of_a_temporary_files_life_leaves_nothing_behind(moment, directory, tmp_path,
                                                                                monkeypatch):
    """Ctrl-C or SIGTERM (a KeyboardInterrupt in the main thread) while a file or folder is written beside its
    destination, at each step of the temporary's life: the destination keeps what it held and no temporary
    stays beside it."""
    from data_tools.io import files

    target = tmp_path / ("seq" if directory else "result.json")
    if directory:
        target.mkdir()
        (target / "meta.json").write_text("earlier")
    else:
        target.write_text("earlier")
    real_open, real_mkdir = os.open, Path.mkdir

    def stop_after(real):
        def call(*args, **kwargs):
            out = real(*args, **kwargs)
            if str(args[0]).startswith(str(tmp_path / ".")):
                raise KeyboardInterrupt  # the moment after the temporary was made
            return out
        return call

    if moment == "making it":
        monkeypatch.setattr(files.secrets, "token_hex", lambda n: (_ for _ in ()).throw(KeyboardInterrupt))
    elif moment == "just made":
        monkeypatch.setattr(files.os, "open", stop_after(real_open))
        monkeypatch.setattr(Path, "mkdir", stop_after(real_mkdir))
    elif moment == "renaming it":
        monkeypatch.setattr(files.os, "replace", lambda *a: (_ for _ in ()).throw(KeyboardInterrupt))
    with pytest.raises(KeyboardInterrupt):
        with files.fresh_beside(target, ".tmp", directory=directory) as fresh:
            assert fresh.parent == tmp_path and fresh.name.startswith(".")
            if moment == "writing it":
                (fresh / "meta.json" if directory else fresh).write_text("new, half")
                raise KeyboardInterrupt
            files.os.replace(fresh, target)  # only "renaming it" gets here
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == [target.name]
    assert (target / "meta.json" if directory else target).read_text() == "earlier"
