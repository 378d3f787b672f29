"""capture end to end on the synthetic MPEG-4 walk: videos and calibration in, poses, BVH, TRC, the triangulated
keypoints and an overlay out, tracked near the known poses; a rerun skips what is done; one camera alone too.

A body of cones is no person to a keypoint detector, so the detector is replaced here by the detector noise
model on the rendered poses (:mod:`data_tools.vision.keypoints.simulate`); the real detector's own tests run on the
real example (``tests/data_tools/test_keypoint_detection.py``)."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import data_tools.vision.keypoints.detect as detect
from data_tools.sequences.rig_formats import write_rig
from data_tools.vision.keypoints.simulate import simulate_sequence_keypoints
from tracker.app.capture import STEPS, capture
from tracker.app.cli import main
from tracker.core.errors import InputError


@pytest.fixture
def simulated_detector(rendered_walk, monkeypatch):
    """The keypoint detector of ``capture`` replaced by the noise model on the rendered walk's true poses."""
    _, rendered, _ = rendered_walk

    def detect_from_truth(seq, views=None, progress=None):
        imported = dataclasses.replace(rendered, rig=seq.rig)  # the imported cameras, in the imported order
        return simulate_sequence_keypoints(imported, np.random.default_rng(7))

    monkeypatch.setattr(detect, "detect_sequence_keypoints", detect_from_truth)


@pytest.mark.slow
def test_capture_tracks_the_videos_and_skips_what_is_done(rendered_walk, simulated_detector, tmp_path):
    folder, rendered, videos = rendered_walk
    write_rig(rendered.rig, tmp_path / "rig.toml")
    out = tmp_path / "capture"
    result = capture(videos, tmp_path / "rig.toml", out, prior="zero-velocity", particles=200, downscale=1)
    for name in ("poses.trc", "poses.bvh", "triangulated.trc", "overlay.mp4", "result.json"):
        assert (out / name).is_file(), name
    found = np.load(out / "run" / "estimates.npz")["markers"]
    errors = np.linalg.norm(found - rendered.groundtruth.markers[:len(found)], axis=-1).mean(axis=-1)
    assert errors.mean() < 80.0 and errors.max() < 120.0, errors  # mm
    assert json.loads((out / "result.json").read_text())["settings"]["prior"] == "zero-velocity"
    again = capture(videos, tmp_path / "rig.toml", out, prior="zero-velocity", particles=200, downscale=1)
    assert again.skipped == [s for s in STEPS if s != "export"]
    (out / "sequence" / "keypoints" / "keypoints.npz").unlink()  # detected again: the start and track follow
    redone = capture(videos, tmp_path / "rig.toml", out, prior="zero-velocity", particles=50, downscale=1)
    assert redone.skipped == ["import", "silhouettes"]
    with pytest.raises(InputError, match="--overwrite"):
        capture(videos, tmp_path / "rig.toml", out, views=[0], prior="zero-velocity", downscale=1)
    assert result.seconds["track"] > 0


@pytest.mark.slow
def test_capture_with_one_camera_from_the_command_line(rendered_walk, simulated_detector, tmp_path, capsys):
    folder, rendered, videos = rendered_walk
    write_rig(rendered.rig, tmp_path / "rig.toml")
    out = tmp_path / "mono"
    assert main(["capture", *map(str, videos), "--calibration", str(tmp_path / "rig.toml"), "--out", str(out),
                 "--views", "2", "--prior", "zero-velocity", "--particles", "100", "--downscale", "1", "-q"]) == 0
    assert "poses.trc" in capsys.readouterr().out
    assert not (out / "triangulated.trc").exists()  # one view triangulates nothing
    assert len(json.loads((out / "sequence" / "cameras.json").read_text())["cameras"]) == 1

    def ground_contact() -> dict | None:
        settings = json.loads((out / "run" / "result.json").read_text())["likelihood_settings"]
        return next((v["ground-contact"] for v in settings.values() if "ground-contact" in v), None)

    assert ground_contact() == {"ground_std": 20.0, "root_height_std": 60.0}  # one camera: on by default
    again = capture(videos, tmp_path / "rig.toml", out, views=[2], prior="zero-velocity", particles=100,
                    downscale=1, ground_std=0.0, root_height_std=0.0)
    assert again.skipped == ["import", "silhouettes", "keypoints", "start"] and ground_contact() is None


def test_capture_refuses_an_unknown_prior_before_any_work(rendered_walk, tmp_path, capsys):
    folder, rendered, videos = rendered_walk
    write_rig(rendered.rig, tmp_path / "rig.toml")
    assert main(["capture", *map(str, videos), "--calibration", str(tmp_path / "rig.toml"), "--out",
                 str(tmp_path / "c"), "--prior", "nonsense"]) == 2
    assert "nonsense" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()


def test_capture_refuses_a_file_as_out_and_a_refused_start_does_not_block_the_next(rendered_walk, tmp_path):
    folder, rendered, videos = rendered_walk
    write_rig(rendered.rig, tmp_path / "rig.toml")
    (tmp_path / "file").write_text("")
    with pytest.raises(InputError, match="not a folder"):
        capture(videos, tmp_path / "rig.toml", tmp_path / "file", downscale=1)
    out = tmp_path / "refused"
    with pytest.raises(InputError, match="frame range 3:2"):
        capture(videos, tmp_path / "rig.toml", out, downscale=1, frames="3:2")
    with pytest.raises(InputError, match="frame range 9:99"):  # not "give --overwrite": nothing was done there
        capture(videos, tmp_path / "rig.toml", out, downscale=1, frames="9:99")


def test_overwrite_replaces_only_a_capture_and_never_its_inputs(rendered_walk, tmp_path):
    """--overwrite starts a capture again; a folder no capture wrote, or one holding the inputs, is kept."""
    import shutil

    folder, rendered, videos = rendered_walk
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    shutil.copy(videos[0], mine / videos[0].name)
    write_rig(rendered.rig, mine / "rig.toml")
    inputs = [mine / videos[0].name, *videos[1:]]
    with pytest.raises(InputError, match="no capture wrote"):
        capture(inputs, mine / "rig.toml", mine, downscale=1, overwrite=True)
    (mine / "capture_source.json").write_text("{}")  # a capture's folder, now holding an input
    with pytest.raises(InputError, match="lies inside the folder"):
        capture(inputs, mine / "rig.toml", mine, downscale=1, overwrite=True)
    assert (mine / "notes.txt").read_text() == "keep me" and (mine / videos[0].name).is_file()
