"""The body's size and first poses from 2-D keypoints, for sequences that have them (``seq/keypoints/``).

1. **Size** (two or more views): the keypoints of the first :data:`MEASURE_FRAMES` frames triangulated robustly
   (:mod:`data_tools.vision.keypoints.triangulate`), the upper arm, forearm, thigh, shank and trunk measured as
   medians over frames, and the body made with them (:func:`data_tools.vision.landmarks.shape_from_landmarks`: the
   default adult at the measured scale, the limbs as measured). With one view nothing can be measured: the
   sequence's own body shape (``meta.json``) or the default adult is kept.
2. **Where and which way**: with two or more views, the pelvis above the triangulated hips' midpoint and the
   heading from the hips' and shoulders' left-to-right direction (the body faces the cross product of its left
   with up); the turned heading is tried too, in case a detector labels the whole person the wrong way round.
   With one view, the pelvis on the ray through the hips' midpoint at the depth where the body's default
   height matches the person's height in pixels, and every :data:`MONOCULAR_HEADINGS`-th heading.
3. **The pose**: from each start (both stances of :data:`STANCES`), the 40 numbers fitted to the frame's
   keypoints in every view (:func:`tracker.core.keypoint_fit.fit_pose`, joint limits respected); the cheapest
   kept. Each further known frame starts from the one before.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.core.body import BodyModel, BodyShape, fifteen_cone_model, stance_pose
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError
from tracker.core.keypoint_fit import MIN_CONFIDENCE, Fitted, fit_pose
from tracker.core.keypoints import KEYPOINT_INDEX
from tracker.core.kinematics import standing_height

#: Frames whose triangulated keypoints measure the body (each length the median over them).
MEASURE_FRAMES = 10
#: Shoulder abduction (radians) of the stances each fit starts from: arms down, T-pose.
STANCES = {"standing": 0.15, "t-pose": np.pi / 2 * 0.95}
#: Heading step (degrees) of the starts with one view.
MONOCULAR_HEADINGS = 45.0
#: Steps of the first frame's fit.
FIT_ITERATIONS = 250


@dataclass
class KeypointStart:
    """First poses ``F x D`` (mm, rad), one per known frame; the body shape and model they are of; the fit's
    cost at the first frame; the standing height (mm); the measured lengths (mm, empty with one view)."""

    poses: np.ndarray
    shape: BodyShape
    model: BodyModel
    cost: float
    height: float
    lengths: dict[str, float]


def _point(points: np.ndarray, name: str) -> np.ndarray:
    return points[..., KEYPOINT_INDEX[name], :]


def keypoint_lengths(points: np.ndarray, source=None) -> dict[str, float]:
    """Upper arm, forearm, thigh, shank and trunk (mm; medians over frames, the two sides averaged) of
    triangulated body keypoints ``T x K x 3`` (mm, NaN where not triangulated); an :class:`InputError` names
    a length no frame measures."""
    def limb(a: str, b: str) -> np.ndarray:
        """Per frame, the mean of the sides measured (NaN where neither is)."""
        sides = np.stack([np.linalg.norm(_point(points, f"{s}_{a}") - _point(points, f"{s}_{b}"), axis=-1)
                          for s in ("left", "right")])
        seen = np.isfinite(sides)
        return np.where(seen, sides, 0.0).sum(axis=0) / np.where(seen.any(axis=0), seen.sum(axis=0), np.nan)

    mid_hip = 0.5 * (_point(points, "left_hip") + _point(points, "right_hip"))
    mid_shoulder = 0.5 * (_point(points, "left_shoulder") + _point(points, "right_shoulder"))
    measured = {"upper arm": limb("shoulder", "elbow"), "forearm": limb("elbow", "wrist"),
                "thigh": limb("hip", "knee"), "shank": limb("knee", "ankle"),
                "trunk": np.linalg.norm(mid_shoulder - mid_hip, axis=-1)}
    out = {}
    for name, values in measured.items():
        values = values[np.isfinite(values)]
        if values.size == 0:
            raise InputError(f"cannot measure the {name}: fewer than two views see its keypoints in any frame",
                             source)
        out[name] = float(np.median(values))
    return out


def _heading(points: np.ndarray) -> float | None:
    """The heading (rad about +z, 0 facing +x) of triangulated keypoints ``K x 3``, or None when neither the
    hips nor the shoulders are both triangulated."""
    left = np.zeros(3)
    for joint in ("hip", "shoulder"):
        d = _point(points, f"left_{joint}") - _point(points, f"right_{joint}")
        if np.all(np.isfinite(d)):
            left += d / max(np.linalg.norm(d), 1e-9)
    left[2] = 0.0
    if np.linalg.norm(left) < 1e-6:
        return None
    forward = np.cross(left, [0.0, 0.0, 1.0])
    return float(np.arctan2(forward[1], forward[0]))


def _multiview_starts(model: BodyModel, points: np.ndarray, source=None) -> np.ndarray:
    """Start poses ``B x D`` from one frame's triangulated keypoints ``K x 3``."""
    hips = np.stack([_point(points, "left_hip"), _point(points, "right_hip")])
    anchor = np.nanmean(hips, axis=0) if np.isfinite(hips).any() else np.nanmean(points, axis=0)
    if not np.all(np.isfinite(anchor)):
        raise InputError("no keypoint of the first frame is seen by two views: cannot place the body", source)
    heading = _heading(points)
    headings = [0.0, np.pi / 2, np.pi, 1.5 * np.pi] if heading is None else [heading, heading + np.pi]
    hip_drop = -0.5 * (model.shape.left_hip_offset[2] + model.shape.right_hip_offset[2])
    starts = []
    for abduction in STANCES.values():
        for h in headings:
            pose = stance_pose(model, abduction)
            pose[:2] = anchor[:2]
            pose[2] = anchor[2] + hip_drop if np.isfinite(hips).all() else model.rest_root_height
            pose[3:6] = (0.0, 0.0, h)
            starts.append(pose)
    return np.array(starts)


def _monocular_starts(model: BodyModel, rig: CameraRig, detections: np.ndarray, source=None) -> np.ndarray:
    """Start poses ``B x D`` from one view's detections ``K x 3``: on the ray through the hips (or all
    keypoints') centre, at the depth where the default stature spans the keypoints' height in pixels."""
    cam = rig[0]
    seen = detections[:, 2] >= MIN_CONFIDENCE
    if seen.sum() < 4:
        raise InputError("the first frame has fewer than 4 confident keypoints: cannot place the body", source)
    xy = detections[seen, :2]
    hips = [KEYPOINT_INDEX["left_hip"], KEYPOINT_INDEX["right_hip"]]
    centre = detections[hips, :2].mean(axis=0) if seen[hips].all() else xy.mean(axis=0)
    span_px = max(np.ptp(xy[:, 1]), 1.0)
    depth = cam.fy * 0.9 * standing_height(model) / span_px  # the keypoints span about 90% of the stature
    ray = np.array([(centre[0] - cam.cx) / cam.fx, (centre[1] - cam.cy) / cam.fy, 1.0]) * depth
    world = cam.R.T @ (ray - np.asarray(cam.t, float))
    starts = []
    for abduction in STANCES.values():
        for h in np.radians(np.arange(0.0, 360.0, MONOCULAR_HEADINGS)):
            pose = stance_pose(model, abduction)
            pose[:2] = world[:2]
            pose[2] = model.rest_root_height
            pose[3:6] = (0.0, 0.0, h)
            starts.append(pose)
    return np.array(starts)


def initialise_from_keypoints(seq, views=None, known_frames: int = 2, shape: BodyShape | None = None
                              ) -> KeypointStart:
    """The body's size and the first ``known_frames`` poses of ``seq`` (a sequence with keypoints) from its
    keypoints in the cameras ``views`` (default all); the module docstring says how. ``shape`` keeps a body
    shape of your own instead of measuring one."""
    from data_tools.vision.keypoints.triangulate import triangulate_keypoints

    if seq.keypoints is None:
        raise InputError("the sequence has no keypoints (pose-tracker keypoints SEQ detects them)", seq.root)
    views = list(range(seq.n_views)) if views is None else list(views)
    if known_frames > seq.n_frames:
        raise InputError(f"{known_frames} known frames asked, the sequence has {seq.n_frames}", seq.root)
    rig = seq.rig.subset(views)
    detections = seq.keypoints.points[:, views]
    lengths: dict[str, float] = {}
    points = None
    if len(views) >= 2:
        frames = min(max(MEASURE_FRAMES, known_frames), seq.n_frames)
        points = triangulate_keypoints(rig, detections[:frames]).points
        if shape is None:
            from data_tools.vision.landmarks import shape_from_landmarks

            lengths = keypoint_lengths(points, seq.root)
            shape = shape_from_landmarks(lengths, seq.root)
    model = fifteen_cone_model(shape if shape is not None else seq.model.shape)
    starts = (_multiview_starts(model, points[0], seq.root) if points is not None
              else _monocular_starts(model, rig, detections[0, 0], seq.root))
    # Every start is fitted through: after a fifth of the steps the turned start can still look the cheaper one.
    first: Fitted = fit_pose(model, rig, detections[0], starts, iterations=FIT_ITERATIONS)
    poses = [first.pose]
    for k in range(1, known_frames):
        poses.append(fit_pose(model, rig, detections[k], poses[-1][None], iterations=100, step=0.02).pose)
    return KeypointStart(np.array(poses), model.shape, model, float(first.costs[first.best]),
                         standing_height(model), lengths)
