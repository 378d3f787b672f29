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
    from tracker.app import api

    argv = ["track", str(synthetic_walk.root), "--prior", "constant-velocity", "--particles", "30",
            "--annealing-layers", "1", "--seed", "3", "--checkpoint-every", "1", "--out", str(tmp_path / "cut")]
    real = api.track
    monkeypatch.setattr(api, "track", lambda *a, on_frame=None, **k: real(
        *a, on_frame=lambda s, e: (on_frame(s, e), stop_after(1)(s, e)), **k))
    assert cli.main(argv) == 130
    monkeypatch.undo()
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
