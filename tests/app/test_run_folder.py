"""A run kept in a folder (:mod:`tracker.app.run_folder`): Python stops and continues it as the command line does,
and either continues a run the other started, to the numbers of an uninterrupted run."""
import json

import numpy as np
import pytest

import tracker
from tracker.app import cli
from tracker.app.run_folder import REQUEST_FILE, TrackingStopped, TrackRequest
from tracker.core.errors import InputError

SETTINGS = dict(particles=30, annealing_layers=1, seed=3, checkpoint_every=1)


def poses(out) -> np.ndarray:
    with np.load(out / "estimates.npz") as f:
        return f["poses"]


def stop_after(frames: int):
    count = {"n": 0}

    def on_frame(step, error):
        count["n"] += 1
        if count["n"] == frames:
            raise KeyboardInterrupt
    return on_frame


def stop_in_the_shell(sequence, out, monkeypatch) -> None:
    """``pose-tracker track`` of :data:`SETTINGS`' run into ``out``, stopped (Ctrl-C) at its first frame."""
    from tracker.app import api

    argv = ["track", str(sequence), "--prior", "constant-velocity", "--particles", "30", "--annealing-layers", "1",
            "--seed", "3", "--checkpoint-every", "1", "--out", str(out)]
    real = api.track
    monkeypatch.setattr(api, "track", lambda *a, on_frame=None, **k: real(
        *a, on_frame=lambda s, e: (on_frame(s, e), stop_after(1)(s, e)), **k))
    assert cli.main(argv) == 130
    monkeypatch.undo()


def test_python_stops_and_continues_a_run_to_the_uninterrupted_numbers(synthetic_walk, tmp_path):
    whole = tracker.track_into(tmp_path / "whole", synthetic_walk.root, "constant-velocity", **SETTINGS)
    assert not (tmp_path / "whole" / REQUEST_FILE).exists()
    with pytest.raises(TrackingStopped) as stop:
        tracker.track_into(tmp_path / "cut", synthetic_walk.root, "constant-velocity", on_frame=stop_after(2),
                           **SETTINGS)
    assert stop.value.resumable and stop.value.partial is not None
    assert json.loads((tmp_path / "cut" / "result.json").read_text())["complete"] is False
    resumed = tracker.resume_tracking(tmp_path / "cut")
    assert np.array_equal(resumed.poses, whole.poses)
    assert np.array_equal(poses(tmp_path / "cut"), poses(tmp_path / "whole"))
    assert not (tmp_path / "cut" / REQUEST_FILE).exists() and not (tmp_path / "cut" / "checkpoint.npz").exists()


def test_python_continues_a_run_the_command_line_started(synthetic_walk, tmp_path, monkeypatch, capsys):
    stop_in_the_shell(synthetic_walk.root, tmp_path / "cut", monkeypatch)
    request = TrackRequest.from_json(json.loads((tmp_path / "cut" / REQUEST_FILE).read_text()),
                                     tmp_path / "cut" / REQUEST_FILE)
    assert request.prior == "constant-velocity" and request.settings["particles"] == 30
    tracker.resume_tracking(tmp_path / "cut")
    tracker.track_into(tmp_path / "whole", synthetic_walk.root, "constant-velocity", **SETTINGS)
    assert np.array_equal(poses(tmp_path / "cut"), poses(tmp_path / "whole"))


def test_another_request_into_an_unfinished_run_is_refused_and_the_same_continues(synthetic_walk, tmp_path):
    with pytest.raises(TrackingStopped):
        tracker.track_into(tmp_path / "cut", synthetic_walk.root, "zero-velocity", on_frame=stop_after(1),
                           **SETTINGS)
    with pytest.raises(InputError, match=r"unfinished run of other arguments \(seed\).*resume_tracking"):
        tracker.track_into(tmp_path / "cut", synthetic_walk.root, "zero-velocity", **{**SETTINGS, "seed": 4})
    tracker.track_into(tmp_path / "cut", synthetic_walk.root, "zero-velocity", **SETTINGS)
    tracker.track_into(tmp_path / "whole", synthetic_walk.root, "zero-velocity", **SETTINGS)
    assert np.array_equal(poses(tmp_path / "cut"), poses(tmp_path / "whole"))


def test_a_stop_before_the_first_frame_leaves_nothing(synthetic_walk, tmp_path, monkeypatch):
    from tracker.app import api

    monkeypatch.setattr(api, "track", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    with pytest.raises(TrackingStopped) as stop:
        tracker.track_into(tmp_path / "run", synthetic_walk.root, "zero-velocity", **SETTINGS)
    assert not stop.value.resumable and not (tmp_path / "run").exists()
    with pytest.raises(InputError, match="no interrupted run"):
        tracker.resume_tracking(tmp_path)


def test_the_same_request_from_python_continues_a_run_the_shell_stopped(synthetic_walk, tmp_path, monkeypatch):
    """The command line names every setting, Python only those given: the same run asked either way is one."""
    stop_in_the_shell(synthetic_walk.root, tmp_path / "cut", monkeypatch)
    tracker.track_into(tmp_path / "cut", synthetic_walk.root, "constant-velocity", **SETTINGS)  # continues it
    tracker.track_into(tmp_path / "whole", synthetic_walk.root, "constant-velocity", **SETTINGS)
    assert np.array_equal(poses(tmp_path / "cut"), poses(tmp_path / "whole"))


def test_a_request_an_earlier_version_kept_continues_from_python_and_the_shell(synthetic_walk, tmp_path, capsys):
    """An unfinished run of an earlier version kept the command line's parsed arguments: both the same command
    again and ``resume_tracking`` continue it (from its first frame: its checkpoint is of that version)."""
    earlier = {"sequence": str(synthetic_walk.root), "prior": "constant-velocity", "out": str(tmp_path / "old"),
               "model": None, "likelihood": None, "views": "0,1", "init": None, "train_mocap": None, "video": None,
               "plugin": [], "overwrite": False, "particles": 30, "annealing_layers": 1, "seed": 3,
               "checkpoint_every": 1, "frames": None, "known_frames": 2, "resampling": "systematic",
               "device": "cpu", "ess_threshold": None, "survival_rate": None, "layer_diffusion_decay": None}
    for name in ("old", "old2"):
        (tmp_path / name).mkdir()
        (tmp_path / name / REQUEST_FILE).write_text(json.dumps({**earlier, "out": str(tmp_path / name)}))
    tracker.resume_tracking(tmp_path / "old")
    argv = ["track", str(synthetic_walk.root), "--prior", "constant-velocity", "--particles", "30", "--views",
            "0,1", "--annealing-layers", "1", "--seed", "3", "--checkpoint-every", "1", "--out", str(tmp_path / "old2")]
    assert cli.main(argv) == 0 and "continuing it" in capsys.readouterr().err
    tracker.track_into(tmp_path / "new", synthetic_walk.root, "constant-velocity", views=[0, 1], **SETTINGS)
    assert np.array_equal(poses(tmp_path / "old"), poses(tmp_path / "new"))
    assert np.array_equal(poses(tmp_path / "old2"), poses(tmp_path / "new"))


def test_a_damaged_request_is_one_line(tmp_path, capsys):
    (tmp_path / REQUEST_FILE).write_text(json.dumps({"format": "pose-tracker track request 1", "sequence": "s",
                                                     "prior": "zero-velocity", "settings": [1]}))
    assert cli.main(["track", "--resume", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "malformed (settings)" in err[0]
    (tmp_path / REQUEST_FILE).write_text(json.dumps({"prior": "zero-velocity", "views": 5}))  # an earlier one's
    assert cli.main(["track", "--resume", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "malformed (KeyError: 'sequence')" in err[0]
