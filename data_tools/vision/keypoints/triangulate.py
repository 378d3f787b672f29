"""Robust triangulation of 2-D keypoints over calibrated views, as Pose2Sim does it, and what follows it.

:func:`triangulate_keypoints` places every keypoint of every frame from a detector's points ``T x V x K x 3``
(pixel x, y, confidence; :mod:`data_tools.sequences.keypoint_file`):

1. it starts from the views whose confidence is at least ``min_confidence`` (0.3, Pose2Sim's
   ``likelihood_threshold_triangulation``) and solves the direct linear transform with each view's equations
   weighted by its confidence (:func:`data_tools.vision.landmarks.dlt_solve`, lens distortion undone as there);
2. while the mean reprojection error over the views in use exceeds ``max_error_px`` and more than
   ``min_views`` (2) views remain, it drops the view whose removal leaves the lowest mean error and solves
   again (one view at a time, greedily; Pose2Sim searches every subset of each size instead: on the
   simulated detector with four views that search placed the limb joints as well or worse (by up to 13 mm
   at 20 % outliers), since the best-fitting pair may hold an outlier that happens to agree with the other
   view);
3. a point whose error still exceeds the bound is left out (NaN), as Pose2Sim leaves it, unless
   ``keep_unresolved``;
4. with ``fix_swaps`` (the default), every view's left/right groups (:data:`tracker.core.keypoints.SWAP_GROUPS`)
   are then checked against the points placed: a group whose points lie, on average, more than
   ``max_error_px`` from their own points' projections and less than half as far from the other side's is
   relabelled, and the frames with a relabelled group are triangulated again (Pose2Sim's
   ``handle_LR_swap`` tries the swapped labels inside its search instead).

**The default bound** (:func:`default_max_error_px`) is Pose2Sim's 15 pixels
(``reproj_error_threshold_triangulation``, set for its 1080-row videos) scaled to the rig's images by their
mean height: 6.7 pixels at 480 rows, 3.8 at 272. A detector's error is a fraction of the person's size in the
image, and the person fills about the same part of the image height in most set-ups, so the bound follows
the height. On :func:`tracker.core.cameras.default_rig` (a person about 170 pixels tall at 480 rows) the
simulated detector's default noise (25 mm, 2.5 pixels per axis) gives inliers a mean error of 2.5 pixels
(99 % below 4.6); the bound is well above that, so few inliers are dropped and outliers (tens of pixels) are.
A bound below about twice the inliers' mean error drops good views and loses more than it gains (at 50 mm of
noise, 5 pixels, the bound of 6.7 placed the limbs 4 mm worse than a plain DLT without outliers): give a
noisier detector a larger bound.

:func:`median_filter` smooths the triangulated trajectories over time (a centred median, NaN-aware) and
:func:`write_keypoints_trc` writes them as a TRC file (:mod:`data_tools.motion.trc`) under OpenPose's and Pose2Sim's
point names (:data:`TRC_NAMES`).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_tools.motion.trc import write_trc
from data_tools.vision.keypoints.layouts import LAYOUTS
from data_tools.vision.landmarks import dlt_rows, dlt_solve, reprojection_errors
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINT_INDEX, KEYPOINTS, SWAP_GROUPS, swap_permutation

#: Confidence a view's point needs to take part (Pose2Sim's ``likelihood_threshold_triangulation``).
MIN_CONFIDENCE = 0.3
#: Pose2Sim's reprojection-error bound (pixels) and the image height (rows) it is set for.
POSE2SIM_MAX_ERROR_PX = 15.0
POSE2SIM_IMAGE_HEIGHT = 1080
#: Fewest views a point is triangulated from.
MIN_VIEWS = 2
#: Frames of the temporal median (:func:`median_filter`).
MEDIAN_WINDOW = 5
#: The keypoints' names in a TRC file, in :data:`tracker.core.keypoints.KEYPOINTS` order: OpenPose's
#: BODY_25B and HALPE_26 names, which Pose2Sim's skeletons and OpenSim models use.
TRC_NAMES: tuple[str, ...] = tuple({v: k for k, v in LAYOUTS["halpe_26"].items()}[name] for name in KEYPOINTS)


@dataclass
class Triangulation:
    """Triangulated keypoints: ``points`` ``T x K x 3`` (mm, world; NaN where not placed), ``errors``
    ``T x V x K`` (pixels: each detected point's distance from its placed point's projection, whether or not
    its view was used; NaN where either is missing), ``used`` ``T x V x K`` (bool: the views a point was placed
    from) and ``swapped`` ``T x V x G`` (bool: the swap groups relabelled before triangulation), ``max_error_px``
    the bound applied. ``errors`` and ``used`` are of the detections as relabelled: where a view's group is
    ``swapped``, its left keypoint's entries are of the point the detector labelled right, and the other way."""

    points: np.ndarray
    errors: np.ndarray
    used: np.ndarray
    swapped: np.ndarray
    max_error_px: float

    @property
    def mean_error(self) -> np.ndarray:
        """Mean reprojection error ``T x K`` (pixels) over the views each point was placed from; NaN where not
        placed."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmean(np.where(self.used, self.errors, np.nan), axis=1)


def default_max_error_px(rig: CameraRig) -> float:
    """The reprojection-error bound (pixels) for the rig's images: Pose2Sim's 15 pixels at 1080 rows, scaled
    by the views' mean height (the module says why)."""
    height = float(np.mean([c.height for c in rig.cameras]))
    return POSE2SIM_MAX_ERROR_PX * height / POSE2SIM_IMAGE_HEIGHT


def _mean_over_views(errors: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(errors, axis=-2)


def _robust(rig: CameraRig, pixels: np.ndarray, confidence: np.ndarray, min_confidence: float,
            max_error: float, min_views: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps 1 and 2 of the module for pixels ``T x V x K x 2`` and confidences ``T x V x K``: points
    ``T x K x 3`` (mm), the views used ``T x V x K`` and their mean reprojection error ``T x K`` (pixels)."""
    V = pixels.shape[1]
    rows = dlt_rows(rig, pixels)  # T x V x K x 2 x 4
    used = (confidence >= min_confidence) & (confidence > 0) & np.isfinite(pixels).all(axis=-1)
    weights = np.where(used, confidence, 0.0)
    points = dlt_solve(rows, weights)
    mean = _mean_over_views(reprojection_errors(rig, points, pixels, used))
    drop = ~np.eye(V, dtype=bool)[:, None, :, None]  # candidate d leaves view d out: V x 1 x V x 1
    while True:
        todo = (mean > max_error) & (used.sum(axis=1) > min_views)  # NaN compares False
        if not todo.any():
            break
        t, k = np.nonzero(todo)
        n = np.arange(t.size)
        w = weights[t, :, k][None, :, :, None] * drop  # V (candidate) x N x V x 1
        candidates = dlt_solve(rows[t, :, k][:, :, None], w)  # V x N x 1 x 3
        errors = reprojection_errors(rig, candidates, pixels[t, :, k][:, :, None], w > 0)  # V x N x V x 1
        cost = _mean_over_views(errors)[..., 0]  # V x N
        cost = np.where(used[t, :, k].T & np.isfinite(cost), cost, np.inf)
        best = np.argmin(cost, axis=0)
        used[t, best, k] = False
        weights[t, best, k] = 0.0
        points[t, k] = candidates[best, n, 0]
        mean[t, k] = cost[best, n]
    return points, used, mean


def _swaps(rig: CameraRig, pixels: np.ndarray, points: np.ndarray, max_error: float) -> np.ndarray:
    """Which swap groups ``T x V x G`` of detections ``T x V x K x 2`` are explained better with their left and
    right exchanged, given the placed points ``T x K x 3`` (step 4 of the module)."""
    projected, _ = rig.project(np.nan_to_num(points))  # T x V x K x 2
    placed = np.isfinite(points).all(axis=-1)[:, None, :]
    out = np.zeros(pixels.shape[:2] + (len(SWAP_GROUPS),), bool)
    for g, (left, right) in enumerate(SWAP_GROUPS):
        idx = [KEYPOINT_INDEX[n] for n in left + right]
        other = [KEYPOINT_INDEX[n] for n in right + left]
        as_is = np.linalg.norm(pixels[:, :, idx] - projected[:, :, idx], axis=-1)
        exchanged = np.linalg.norm(pixels[:, :, other] - projected[:, :, idx], axis=-1)
        ok = np.isfinite(as_is) & np.isfinite(exchanged) & placed[:, :, idx] & placed[:, :, other]
        count = ok.sum(axis=-1)
        with np.errstate(invalid="ignore"):
            as_is = np.where(ok, as_is, 0.0).sum(axis=-1) / count
            exchanged = np.where(ok, exchanged, 0.0).sum(axis=-1) / count
        out[:, :, g] = (count > 0) & (as_is > max_error) & (exchanged < 0.5 * as_is)
    return out


def triangulate_keypoints(rig: CameraRig, detections: np.ndarray, min_confidence: float = MIN_CONFIDENCE,
                          max_error_px: float | None = None, min_views: int = MIN_VIEWS, fix_swaps: bool = True,
                          keep_unresolved: bool = False) -> Triangulation:
    """Robust triangulation (the module says how) of detections ``T x V x K x 3`` (pixel x, y, confidence in
    [0, 1]; NaN pixels or confidence 0 where not found) in the rig's ``V`` views. ``max_error_px`` (pixels)
    defaults to :func:`default_max_error_px`; left/right swaps are relabelled only for the ``K`` body keypoints
    (:data:`tracker.core.keypoints.KEYPOINTS`)."""
    detections = np.asarray(detections, float)
    if detections.ndim != 4 or detections.shape[1] != len(rig) or detections.shape[-1] != 3:
        raise InputError(f"detections must be T x {len(rig)} x K x 3 (x, y, confidence), got {detections.shape}")
    if min_views < 2:
        raise InputError(f"a point needs at least 2 views to be triangulated, got min_views={min_views}")
    max_error = default_max_error_px(rig) if max_error_px is None else float(max_error_px)
    pixels, confidence = detections[..., :2].copy(), np.nan_to_num(detections[..., 2])
    points, used, mean = _robust(rig, pixels, confidence, min_confidence, max_error, min_views)
    swapped = np.zeros(detections.shape[:2] + (len(SWAP_GROUPS),), bool)
    if fix_swaps and detections.shape[2] == len(KEYPOINTS):
        swapped = _swaps(rig, pixels, np.where((mean <= max_error)[..., None], points, np.nan), max_error)
        frames = np.nonzero(swapped.any(axis=(1, 2)))[0]
        for g in range(len(SWAP_GROUPS)):
            order = swap_permutation((g,))
            where = swapped[:, :, g, None]
            pixels = np.where(where[..., None], pixels[:, :, order], pixels)
            confidence = np.where(where, confidence[:, :, order], confidence)
        if frames.size:
            again = _robust(rig, pixels[frames], confidence[frames], min_confidence, max_error, min_views)
            points[frames], used[frames], mean[frames] = again
    if not keep_unresolved:
        unresolved = ~(mean <= max_error)
        points[unresolved] = np.nan
        used &= ~unresolved[:, None, :]
    errors = reprojection_errors(rig, points, pixels, np.isfinite(pixels).all(axis=-1) & (confidence > 0))
    return Triangulation(points, errors, used, swapped, max_error)


def median_filter(points: np.ndarray, window: int = MEDIAN_WINDOW, fill: bool = False) -> np.ndarray:
    """Trajectories ``T x ...`` (any trailing shape, e.g. ``T x K x 3`` mm) smoothed over time: each value
    the median of the finite values in a centred window of ``window`` frames (odd; shorter at the ends), each
    coordinate on its own. A median keeps steps and ignores a stray frame, where a Butterworth low-pass
    (Pose2Sim's default) needs gaps filled first and spreads an outlier over its neighbours. Values NaN in the
    input stay NaN unless ``fill`` (then each takes the median of the finite values in its window, NaN where
    there are none)."""
    points = np.asarray(points, float)
    if window < 1 or window % 2 == 0:
        raise InputError(f"the median window must be an odd number of frames >= 1, got {window}")
    half = window // 2
    padded = np.concatenate([np.full((half,) + points.shape[1:], np.nan), points,
                             np.full((half,) + points.shape[1:], np.nan)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, window, axis=0)  # T x ... x window
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        out = np.nanmedian(windows, axis=-1)
    return out if fill else np.where(np.isfinite(points), out, np.nan)


def write_keypoints_trc(path: str | Path, points: np.ndarray, fps: float, unit: str = "m") -> Path:
    """Write triangulated keypoints ``T x K x 3`` (mm, world, :data:`tracker.core.keypoints.KEYPOINTS` order;
    NaN where missing) as a TRC file (:func:`data_tools.motion.trc.write_trc`: y up, in ``unit``) under
    :data:`TRC_NAMES`; returns the path."""
    write_trc(path, TRC_NAMES, points, fps, unit)
    return Path(path)
