"""Time-warping pose clips: the same motion played faster or slower, still sampled at the clip's frame rate.

A learned prior trained on people who walk at 1.1-1.4 m/s walks on at that pace when it tracks someone who
walks at 0.6 m/s (docs/methods_report.md). Training on every clip also replayed at other speeds shows the
model the same gaits at other paces. A clip ``T x D`` replayed at ``speed`` is sampled at the times
``k * speed`` (frames of the original, ``k = 0, 1, ...`` while ``k * speed <= T - 1``), so ``speed`` 0.5
gives ``2T - 1`` frames with half the per-frame motion and ``speed`` 2 about half as many with twice the
motion. The frame rate does not change: the result is another clip at the same rate.

Positions (the root's, in mm) and the angles of 1- and 2-dof joints are interpolated linearly; the
exponential maps of the root's orientation and of the ball joints by spherical interpolation between the
two neighbouring rotations (along the shortest rotation between them), each result on the branch of the
exp map nearest the linear interpolation of the original, continuous, exp maps, so a warped clip is as
continuous as its source even where the rotation angle passes pi. A speed of 1 returns the clip unchanged.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from tracker.core.body import BALL, FREE, BodyModel
from tracker.core.errors import InputError
from tracker.core.rotations import continuous_exp_maps, exp_map_to_matrix, matrix_to_exp_map

#: The slowest and fastest playback speed a training clip may be replayed at.
MIN_SPEED, MAX_SPEED = 0.1, 10.0


def exp_map_triples(body_model: BodyModel) -> list[tuple[int, int, int]]:
    """The pose indices of every exponential map of ``body_model``: the root's orientation (a free joint's
    last three numbers) and each ball joint's three."""
    triples = []
    for link in body_model.links:
        if link.joint == FREE:
            triples.append(tuple(link.dofs[3:6]))
        elif link.joint == BALL:
            triples.append(tuple(link.dofs[:3]))
    return [tuple(int(i) for i in t) for t in triples]


def warped_length(n_frames: int, speed: float) -> int:
    """Frames of a clip of ``n_frames`` replayed at ``speed``: the samples ``k * speed <= n_frames - 1``."""
    return int(np.floor((n_frames - 1) / speed + 1e-9)) + 1


def time_warp_clip(poses: np.ndarray, speed: float, exp_maps: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """The clip ``poses`` (``T x D``, T >= 2) replayed at ``speed`` (see the module docstring); ``exp_maps``
    are the index triples of its exponential maps (:func:`exp_map_triples`), every other number is
    interpolated linearly."""
    poses = np.asarray(poses, float)
    if poses.ndim != 2 or len(poses) < 2:
        raise InputError(f"a clip to time-warp needs at least 2 frames of poses (T x D), got {poses.shape}")
    speed = float(speed)
    if not MIN_SPEED <= speed <= MAX_SPEED:
        raise InputError(f"time-warp speed must lie in [{MIN_SPEED:g}, {MAX_SPEED:g}], got {speed!r}")
    if speed == 1.0:
        return poses.copy()
    return sample_clip(poses, np.arange(warped_length(len(poses), speed)) * speed, exp_maps)


def sample_clip(poses: np.ndarray, times: np.ndarray, exp_maps: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """The clip ``poses`` (``T x D``, T >= 2) at the fractional frame indices ``times`` (``N``, each in
    [0, T - 1]): positions and 1-/2-dof angles interpolated linearly, the exponential maps ``exp_maps`` by
    spherical interpolation (see the module docstring). A whole-number time returns that frame exactly and
    reads no other (a frame never read may hold any finite numbers). Returns ``N x D``."""
    poses = np.asarray(poses, float)
    T = len(poses)
    t = np.asarray(times, float)
    if poses.ndim != 2 or T < 2 or t.ndim != 1 or not np.all((t >= 0) & (t <= T - 1)):
        raise InputError(f"sampling a clip of {poses.shape} poses needs T >= 2 and times in [0, T - 1]")
    i0 = np.minimum(np.floor(t).astype(int), T - 2)
    a = t - i0  # in [0, 1]; 1 only at the last frame when it falls on the clip's end
    lo, hi = poses[i0], poses[i0 + 1]
    out = (1.0 - a)[:, None] * lo + a[:, None] * hi
    exact_lo, exact_hi = a == 0.0, a == 1.0
    for idx in exp_maps:
        idx = list(idx)
        R0, R1 = exp_map_to_matrix(lo[:, idx]), exp_map_to_matrix(hi[:, idx])
        step = matrix_to_exp_map(np.swapaxes(R0, -1, -2) @ R1)  # the shortest rotation from R0 to R1
        slerp = matrix_to_exp_map(R0 @ exp_map_to_matrix(a[:, None] * step))
        # The equivalent exp map nearest the linear interpolation of the (continuous) source exp maps.
        near = continuous_exp_maps(np.stack([out[:, idx], slerp], axis=-2), time_axis=-2)[:, 1]
        near[exact_lo] = lo[exact_lo][:, idx]
        near[exact_hi] = hi[exact_hi][:, idx]
        out[:, idx] = near
    return out


def parse_speeds(text, what: str = "time_warp") -> tuple[float, ...]:
    """Playback speeds from ``"0.6,0.8,1,1.25"`` (or a list of numbers): each finite, in
    [:data:`MIN_SPEED`, :data:`MAX_SPEED`], at least one, duplicates dropped (first kept). Anything else is
    one :class:`InputError` naming ``what`` and the range."""
    rule = (f"{what} must be comma-separated playback speeds, each in [{MIN_SPEED:g}, {MAX_SPEED:g}] "
            f"(e.g. 0.6,0.8,1,1.25)")
    items = list(text) if isinstance(text, (list, tuple)) else str(text).strip().strip("[]").split(",")
    try:
        speeds = [float(str(s).strip()) for s in items]
    except ValueError:
        raise InputError(f"{rule}, got {text!r}") from None
    if not speeds or not all(np.isfinite(s) and MIN_SPEED <= s <= MAX_SPEED for s in speeds):
        raise InputError(f"{rule}, got {text!r}")
    return tuple(dict.fromkeys(speeds))
