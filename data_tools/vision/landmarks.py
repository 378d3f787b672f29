"""The person's segment lengths from image landmarks triangulated over calibrated cameras.

A silhouette tells where the body is, not how long its bones are (a likelihood that rewards a body inside the
silhouette shortens limbs). Joint centres do: MediaPipe's BlazePose (the model the person segmentation runs) also
gives 33 image landmarks per view with a visibility each. This module

1. runs it over each camera's first frames (:func:`view_landmarks`);
2. triangulates every landmark of every frame by the direct linear transform over the views that see it with a
   visibility of at least :data:`MIN_VISIBILITY` (:func:`triangulate`: undistorted normalised coordinates, one
   homogeneous least-squares solve), at least two views (the equations and the solve, :func:`dlt_rows` and
   :func:`dlt_solve`, batched and weighted, also serve the robust keypoint triangulation of
   :mod:`data_tools.vision.keypoints.triangulate`);
3. reads the lengths off the 3-D points, each the median over frames (:func:`segment_lengths`: upper arm,
   forearm, thigh, shank, both sides averaged, and the trunk between the hips' and the shoulders' midpoints);
4. builds the body shape with them (:func:`shape_from_landmarks`): the default adult scaled to the measured
   lengths as a whole, then the four limbs' lengths set as measured.

Landmarks are not the body model's joint centres: on the real four-camera example the trunk between
BlazePose's shoulders' and hips' midpoints measures 568 mm, where the default proportions at the person's size
have 473 (and Pose2Sim's reconstruction, from another detector's keypoints, 539), and BlazePose has no point
on the head's top. So the trunk, head, widths and radii follow the one scale, and only the limbs take their own
lengths. Measured on that example (see the real-video guide), a
body with every length as measured (trunk, head to the ears, shoulder and hip widths too) tracked further from
a reference reconstruction than the one-scale body (a mean per-joint distance of 150.9 mm against 145.2, over
seeds 0 to 7); with the limbs alone it tracked as close (144.3).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterable, Iterator

import numpy as np

from tracker.core.body import BodyShape, default_shape, scaled_shape
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError

#: BlazePose's 33 landmarks, in its order.
BLAZEPOSE = ("nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
             "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
             "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
             "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip", "right_hip",
             "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel", "right_heel",
             "left_foot_index", "right_foot_index")
_L = {name: i for i, name in enumerate(BLAZEPOSE)}
#: Visibility (0 to 1, BlazePose's own) a landmark needs in a view to take part in its triangulation.
MIN_VISIBILITY = 0.5
#: How many first frames are measured (each length is the median over them).
FRAMES = 10
#: The measured lengths (mm), in the order :func:`segment_lengths` gives them.
LENGTHS = ("upper arm", "forearm", "thigh", "shank", "trunk")


def view_landmarks(frames: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
    """BlazePose's landmarks ``33 x 3`` (pixel x, y of the pixel-centre convention; visibility 0 to 1) in each of
    one camera's frames (``H x W x 3`` RGB uint8, in order; video mode); all NaN where it finds no person
    (:func:`data_tools.vision.person_segmentation.pose_landmarks`)."""
    from data_tools.vision.person_segmentation import pose_landmarks

    return pose_landmarks(frames)


def _normalised(rig: CameraRig, v: int, pixels: np.ndarray, iterations: int = 200) -> np.ndarray:
    """Undistorted normalised coordinates ``(..., 2)`` of view ``v``'s pixels ``(..., 2)``: skew removed, then the
    distortion of :mod:`tracker.core.cameras` inverted by fixed-point iteration."""
    cam = rig[v]
    pixels = np.asarray(pixels, float)
    yd = (pixels[..., 1] - cam.cy) / cam.fy
    xd = (pixels[..., 0] - cam.cx) / cam.fx - cam.skew * yd
    k1, k2, p1, p2, k3 = cam.dist
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations if any(cam.dist) else 0):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        x, y = ((xd - 2.0 * p1 * x * y - p2 * (r2 + 2.0 * x * x)) / radial,
                (yd - p1 * (r2 + 2.0 * y * y) - 2.0 * p2 * x * y) / radial)
    return np.stack([x, y], axis=-1)


def dlt_rows(rig: CameraRig, pixels: np.ndarray) -> np.ndarray:
    """The direct linear transform's two equations ``(..., V, K, 2, 4)`` for each pixel ``(..., V, K, 2)`` of the
    rig's ``V`` views (undistorted normalised coordinates; camera centres in metres, so that the four unknowns
    are of one scale). A NaN pixel gives finite rows: its weight in :func:`dlt_solve` must be 0."""
    pixels = np.nan_to_num(np.asarray(pixels, float))
    V = pixels.shape[-3]
    if V != len(rig):
        raise ValueError(f"pixels of {V} views for a rig of {len(rig)}")
    rows = np.zeros(pixels.shape[:-1] + (2, 4))
    for v in range(V):
        xy = _normalised(rig, v, pixels[..., v, :, :])
        P = np.concatenate([rig[v].R, np.asarray(rig[v].t, float)[:, None] / 1000.0], axis=1)  # metres: balanced
        rows[..., v, :, 0, :] = xy[..., :1] * P[2] - P[0]
        rows[..., v, :, 1, :] = xy[..., 1:] * P[2] - P[1]
    return rows


def dlt_solve(rows: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """World points ``(..., K, 3)`` (mm) from the equations ``(..., V, K, 2, 4)`` of :func:`dlt_rows`, each view's
    two scaled by its weight ``(..., V, K)`` (>= 0; 0 leaves the view out, a detector's confidence weights it as
    Pose2Sim does), by one homogeneous least-squares solve per point; NaN for a point with fewer than two views
    of positive weight."""
    weights = np.asarray(weights, float)
    A = np.moveaxis(rows * weights[..., None, None], -4, -3)  # ..., K, V, 2, 4
    A = A.reshape(A.shape[:-3] + (-1, 4))
    X = np.linalg.svd(A)[2][..., -1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        points = X[..., :3] / X[..., 3:] * 1000.0
    points[(weights > 0).sum(axis=-2) < 2] = np.nan
    return points


def triangulate(rig: CameraRig, pixels: np.ndarray, seen: np.ndarray, weights: np.ndarray | None = None
                ) -> np.ndarray:
    """World points ``(..., K, 3)`` (mm) from their pixels ``(..., V, K, 2)`` in the rig's ``V`` views, each by
    the direct linear transform over the views where ``seen`` (``(..., V, K)`` bool) holds, each view weighted by
    ``weights`` (``(..., V, K)``, default 1: :func:`dlt_solve`); NaN for a point seen in fewer than two views."""
    seen = np.asarray(seen, bool)
    w = seen if weights is None else np.where(seen, np.asarray(weights, float), 0.0)
    return dlt_solve(dlt_rows(rig, pixels), w)


def reprojection_errors(rig: CameraRig, points: np.ndarray, pixels: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Distance (pixels) ``(..., V, K)`` between each seen landmark's pixel ``(..., V, K, 2)`` and its
    triangulated point ``(..., K, 3)`` projected into that view; NaN where unseen or untriangulated."""
    points = np.asarray(points, float)
    projected, _ = rig.project(np.nan_to_num(points))
    errors = np.linalg.norm(projected - pixels, axis=-1)
    return np.where(np.asarray(seen, bool) & np.isfinite(points[..., 0])[..., None, :], errors, np.nan)


@dataclass
class Measured:
    """Landmarks triangulated over a sequence's first frames: ``points`` ``T x 33 x 3`` (mm, NaN where fewer
    than two views saw one), the reprojection ``errors`` ``T x V x 33`` (pixels, NaN where unused) and the
    ``lengths`` (mm, :data:`LENGTHS`, medians over frames)."""

    points: np.ndarray
    errors: np.ndarray
    lengths: dict[str, float]


def sequence_landmarks(seq, frames: int = FRAMES) -> np.ndarray:
    """BlazePose's landmarks ``T x V x 33 x 3`` (:func:`view_landmarks`) in the first ``frames`` frames (at most
    the sequence's) of every view of ``seq`` (a :class:`~data_tools.sequences.sequence.Sequence`)."""
    T = min(frames, seq.n_frames)
    return np.stack([np.stack(list(view_landmarks(seq.image(k, v) for k in range(T))))
                     for v in range(seq.n_views)], axis=1)


def measure(rig: CameraRig, landmarks: np.ndarray, source: str | Path | None = None) -> Measured:
    """Triangulate landmarks ``T x V x 33 x 3`` (pixels and visibility, :func:`sequence_landmarks`) seen by the
    rig's ``V`` views and measure the person; an :class:`InputError` naming ``source`` when a length cannot be
    measured (too few views see its landmarks)."""
    seen = landmarks[..., 2] >= MIN_VISIBILITY
    points = np.stack([triangulate(rig, lm[:, :, :2], s) for lm, s in zip(landmarks, seen)])
    errors = np.stack([reprojection_errors(rig, p, lm[:, :, :2], s) for p, lm, s in zip(points, landmarks, seen)])
    return Measured(points, errors, segment_lengths(points, source))


def segment_lengths(points: np.ndarray, source: str | Path | None = None) -> dict[str, float]:
    """The person's lengths (mm, :data:`LENGTHS`) from BlazePose landmarks ``T x 33 x 3`` (mm): each the median
    over frames, the limbs' left and right averaged, the trunk from the hips' to the shoulders' midpoint. An
    :class:`InputError` names a length no frame measures."""
    def at(name: str) -> np.ndarray:
        return points[:, _L[name]]

    def median(d: np.ndarray, what: str) -> float:
        d = d[np.isfinite(d)]
        if d.size == 0:
            raise InputError(f"cannot measure the {what}: fewer than two views see its landmarks in any frame",
                             source)
        return float(np.median(d))

    def limb(a: str, b: str, what: str) -> float:
        sides = np.stack([np.linalg.norm(at(f"{s}_{a}") - at(f"{s}_{b}"), axis=-1) for s in ("left", "right")])
        both = np.isfinite(sides).any(axis=0)
        return median(np.nanmean(sides[:, both], axis=0), what)

    trunk = 0.5 * (at("left_shoulder") + at("right_shoulder") - at("left_hip") - at("right_hip"))
    return {"upper arm": limb("shoulder", "elbow", "upper arm"), "forearm": limb("elbow", "wrist", "forearm"),
            "thigh": limb("hip", "knee", "thigh"), "shank": limb("knee", "ankle", "shank"),
            "trunk": median(np.linalg.norm(trunk, axis=-1), "trunk")}


def landmark_scale(lengths: dict[str, float]) -> float:
    """The measured thigh, shank, trunk and upper arm together (mm, :func:`segment_lengths`) over the default
    adult's (the trunk between the hip and shoulder joints' midpoints: the torso less the shoulders' drop below
    the thorax, plus the hips' below the pelvis origin)."""
    base = default_shape()
    L = base.lengths
    trunk = L["torso"] + base.left_shoulder_offset[2] - base.left_hip_offset[2]
    default = L["left_upper_leg"] + L["left_lower_leg"] + trunk + L["left_upper_arm"]
    return (lengths["thigh"] + lengths["shank"] + lengths["trunk"] + lengths["upper arm"]) / default


def shape_from_landmarks(lengths: dict[str, float], source: str | Path | None = None) -> BodyShape:
    """The body shape for the measured ``lengths`` (mm, :func:`segment_lengths`): the default adult at
    :func:`landmark_scale` (lengths, offsets and radii alike), with both upper arms, forearms, thighs and shanks
    as measured."""
    shape = scaled_shape(default_shape(), landmark_scale(lengths))
    limbs = {"upper_arm": "upper arm", "lower_arm": "forearm", "upper_leg": "thigh", "lower_leg": "shank"}
    new = dict(shape.lengths)
    for segment, name in limbs.items():
        for side in ("left", "right"):
            new[f"{side}_{segment}"] = float(lengths[name])
    return replace(shape, lengths=new).validate(source)
