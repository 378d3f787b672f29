"""The body-centred invariant pose representation (Taylor 2009, Sec. 3.2), forward and inverse.

A pose sequence ``(..., T, 40)`` becomes ``(..., T, 40)`` invariant features:
the root's six numbers are replaced by

=====  ==================  ===============================================
index  name                meaning
=====  ==================  ===============================================
0      forward_velocity    ground-plane step to the next frame along the heading (mm/frame)
1      lateral_velocity    the same step toward the body's left (mm/frame)
2      height              root z (mm)
3      pitch               root pitch (rad), see below
4      roll                root roll (rad)
5      yaw_rate            heading change to the next frame (rad/frame)
=====  ==================  ===============================================

and the 34 joint numbers stay as they are. The root rotation is decomposed as
``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the body faces +x at rest, so yaw is the
heading of its forward axis, Taylor's eq. 3.9). Taylor's pitch and roll
(eqs. 3.7, 3.8) are angles of the body axes with the vertical; his roll leaves
the sign of the lean ambiguous, so we use the equivalent Euler pair, which is
exactly invertible while the body is less than 90 degrees from upright.

Velocities are forward differences (eqs. 3.10-3.16): frame t holds the step
from t to t+1; the last frame repeats the step before it (constant velocity).
The inverse integrates heading and ground position from a known start
(``start_xy`` mm and ``start_yaw`` rad of frame 0). Forward then inverse
reproduces the poses to float precision; root exp maps come back continuous in
time (see :func:`tracker.core.rotations.continuous_exp_maps`).

:class:`FeatureNormaliser` drops constant dimensions and scales the rest to
zero mean, unit variance (Sec. 3.2.5); it is saved with every learned prior.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from tracker.core.errors import InputError

ROOT_FEATURE_NAMES = ("forward_velocity", "lateral_velocity", "height", "pitch", "roll", "yaw_rate")
N_ROOT = 6
#: Feature indices of the root's step to the next frame (forward, lateral velocity, yaw rate): with forward
#: differences a frame's features hold the step *to the next* frame.
STEP_FEATURES = (0, 1, 5)


def posture_features(n_features: int) -> list[int]:
    """Indices of the posture angles (rad) among ``n_features`` invariant features: the root's pitch and roll and
    every joint angle (the features after the root's six); not the ground steps, the height or the heading rate."""
    return [3, 4] + list(range(N_ROOT, n_features))


def feature_names(dof_names: Sequence[str]) -> list[str]:
    """Names of the invariant features for a pose layout whose first 6 numbers are the root."""
    return list(ROOT_FEATURE_NAMES) + list(dof_names[N_ROOT:])


def _check(poses: np.ndarray, what: str) -> np.ndarray:
    poses = np.asarray(poses, dtype=float)
    if poses.ndim < 2 or poses.shape[-1] < N_ROOT + 1:
        raise InputError(f"{what} must have shape (..., T, D) with D > 6, got {poses.shape}")
    if poses.shape[-2] < 2:
        raise InputError(f"{what} need at least 2 frames to define velocities, got {poses.shape[-2]}")
    if not np.all(np.isfinite(poses)):
        raise InputError(f"{what} contain NaN or infinite values")
    return poses


def heading(poses: np.ndarray) -> np.ndarray:
    """Unwrapped heading (yaw, rad) ``(..., T)`` of poses ``(..., T, D)``."""
    from tracker.core.rotations import exp_map_to_matrix, matrix_to_yaw_pitch_roll  # numba: loaded when first used

    yaw, _, _ = matrix_to_yaw_pitch_roll(exp_map_to_matrix(poses[..., 3:6]))
    return np.unwrap(yaw, axis=-1)


def poses_to_invariant(poses: np.ndarray) -> np.ndarray:
    """Invariant features ``(..., T, D)`` of pose sequences ``(..., T, D)`` (see module docstring)."""
    from tracker.core.rotations import exp_map_to_matrix, matrix_to_yaw_pitch_roll

    poses = _check(poses, "poses")
    R = exp_map_to_matrix(poses[..., 3:6])
    yaw, pitch, roll = matrix_to_yaw_pitch_roll(R)
    yaw = np.unwrap(yaw, axis=-1)
    step = np.diff(poses[..., :2], axis=-2)  # (..., T-1, 2)
    step = np.concatenate([step, step[..., -1:, :]], axis=-2)
    dyaw = np.diff(yaw, axis=-1)
    dyaw = np.concatenate([dyaw, dyaw[..., -1:]], axis=-1)
    c, s = np.cos(yaw), np.sin(yaw)
    forward = step[..., 0] * c + step[..., 1] * s
    lateral = -step[..., 0] * s + step[..., 1] * c
    root = np.stack([forward, lateral, poses[..., 2], pitch, roll, dyaw], axis=-1)
    return np.concatenate([root, poses[..., N_ROOT:]], axis=-1)


def invariant_to_poses(features: np.ndarray, start_xy: np.ndarray, start_yaw: np.ndarray,
                       reference_exp_map: np.ndarray | None = None) -> np.ndarray:
    """Pose sequences ``(..., T, D)`` from invariant features ``(..., T, D)``.

    ``start_xy`` ``(..., 2)`` (mm) and ``start_yaw`` ``(...)`` (rad) are the
    ground position and heading of frame 0. Frame t's position and heading are
    integrated from the steps held by frames 0 .. t-1. Root exp maps are made
    continuous in time, starting from the branch nearest ``reference_exp_map``
    ``(..., 3)`` when given (the pose before frame 0), else from the principal one.
    """
    from tracker.core.rotations import continuous_exp_maps, matrix_to_exp_map, yaw_pitch_roll_to_matrix

    f = np.asarray(features, dtype=float)
    if f.ndim < 2 or f.shape[-1] < N_ROOT + 1:
        raise InputError(f"features must have shape (..., T, D) with D > 6, got {f.shape}")
    start_xy = np.asarray(start_xy, float)
    start_yaw = np.asarray(start_yaw, float)
    zeros = np.zeros(f.shape[:-2] + (1,))
    yaw = start_yaw[..., None] + np.concatenate([zeros, np.cumsum(f[..., :-1, 5], axis=-1)], axis=-1)
    c, s = np.cos(yaw), np.sin(yaw)
    dx = f[..., 0] * c - f[..., 1] * s
    dy = f[..., 0] * s + f[..., 1] * c
    x = start_xy[..., 0, None] + np.concatenate([zeros, np.cumsum(dx[..., :-1], axis=-1)], axis=-1)
    y = start_xy[..., 1, None] + np.concatenate([zeros, np.cumsum(dy[..., :-1], axis=-1)], axis=-1)
    R = yaw_pitch_roll_to_matrix(yaw, f[..., 3], f[..., 4])
    if reference_exp_map is None:
        rot = continuous_exp_maps(matrix_to_exp_map(R), time_axis=-2)
    else:
        ref = np.asarray(reference_exp_map, float)[..., None, :]
        rot = continuous_exp_maps(np.concatenate([ref, matrix_to_exp_map(R)], axis=-2), time_axis=-2)[..., 1:, :]
    root = np.concatenate([np.stack([x, y, f[..., 2]], axis=-1), rot], axis=-1)
    return np.concatenate([root, f[..., N_ROOT:]], axis=-1)


def start_of(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ground position ``(..., 2)`` and heading ``(...)`` of frame 0 of ``(..., T, D)`` poses."""
    poses = np.asarray(poses, float)
    return poses[..., 0, :2], heading(poses[..., :1, :])[..., 0]


@dataclass
class FeatureNormaliser:
    """Zero-mean, unit-variance scaling of invariant features, dropping constant dimensions.

    ``mean``, ``std`` ``(D,)``; ``keep`` ``(D,)`` bool. ``transform`` maps
    ``(..., D)`` -> ``(..., K)`` (K kept dimensions); ``inverse`` maps back,
    restoring dropped dimensions to their (constant) training value.
    """

    mean: np.ndarray
    std: np.ndarray
    keep: np.ndarray
    names: list[str]

    #: A dimension whose standard deviation is below this (mm or rad) is constant.
    CONSTANT_TOL = 1e-6

    @classmethod
    def fit(cls, features: np.ndarray | Sequence[np.ndarray], names: Sequence[str]) -> "FeatureNormaliser":
        """Statistics of features ``(T, D)`` or a list of such arrays (several clips)."""
        arrays = [features] if isinstance(features, np.ndarray) else list(features)
        if not arrays:
            raise InputError("no feature arrays to fit normalisation statistics on")
        X = np.concatenate([np.asarray(a, float).reshape(-1, np.asarray(a).shape[-1]) for a in arrays])
        if X.shape[-1] != len(names):
            raise InputError(f"features have {X.shape[-1]} dimensions but {len(names)} names were given")
        mean = X.mean(axis=0)
        std = X.std(axis=0)
        keep = std > cls.CONSTANT_TOL
        return cls(mean, np.where(keep, std, 1.0), keep, list(names))

    @property
    def n_kept(self) -> int:
        return int(self.keep.sum())

    @property
    def kept_names(self) -> list[str]:
        return [n for n, k in zip(self.names, self.keep) if k]

    def transform(self, features: np.ndarray) -> np.ndarray:
        f = np.asarray(features, float)
        if f.shape[-1] != self.mean.size:
            raise InputError(f"features have {f.shape[-1]} dimensions; this normaliser expects {self.mean.size}")
        return ((f - self.mean) / self.std)[..., self.keep]

    def inverse(self, normalised: np.ndarray) -> np.ndarray:
        z = np.asarray(normalised, float)
        if z.shape[-1] != self.n_kept:
            raise InputError(f"normalised features have {z.shape[-1]} dimensions; expected {self.n_kept}")
        out = np.broadcast_to(self.mean, z.shape[:-1] + self.mean.shape).copy()
        out[..., self.keep] = z * self.std[self.keep] + self.mean[self.keep]
        return out

    def to_arrays(self, prefix: str = "normaliser_") -> dict[str, np.ndarray]:
        return {prefix + "mean": self.mean, prefix + "std": self.std, prefix + "keep": self.keep,
                prefix + "names": np.array(self.names)}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "normaliser_", source: str | None = None) -> "FeatureNormaliser":
        try:
            mean = np.asarray(arrays[prefix + "mean"], float)
            std = np.asarray(arrays[prefix + "std"], float)
            keep = np.asarray(arrays[prefix + "keep"], bool)
            names = [str(n) for n in arrays[prefix + "names"]]
        except KeyError as exc:
            raise InputError(f"normalisation statistics lack {exc.args[0]!r}", source) from None
        if not (mean.shape == std.shape == keep.shape == (len(names),)):
            raise InputError("normalisation statistics have inconsistent shapes", source)
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std > 0)):
            raise InputError("normalisation statistics must be finite with positive scales", source)
        return cls(mean, std, keep, names)

    def save(self, path: str | Path) -> None:
        np.savez(path, **self.to_arrays())

    @classmethod
    def load(cls, path: str | Path) -> "FeatureNormaliser":
        try:
            with np.load(path, allow_pickle=False) as data:
                return cls.from_arrays(data, source=str(path))
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read normalisation statistics: {exc}", path) from None



def next_poses(previous: np.ndarray, previous_features: np.ndarray, features: np.ndarray) -> np.ndarray:
    """One step of :func:`invariant_to_poses` for a batch: poses ``(..., D)`` at frame t.

    ``previous`` ``(..., D)`` are the poses at t-1; ``previous_features``
    ``(..., D)`` are frame t-1's invariant features, whose velocities and yaw
    rate (the step t-1 -> t) move the root; ``features`` ``(..., D)`` give frame
    t's height, pitch, roll and joints. The root exp map is kept on the branch
    nearest the previous pose's, so particle means stay meaningful.
    """
    prev = np.asarray(previous, float)
    pair = np.stack([np.asarray(previous_features, float), np.asarray(features, float)], axis=-2)
    return invariant_to_poses(pair, prev[..., :2], heading(prev[..., None, :])[..., 0], prev[..., 3:6])[..., 1, :]


def pending_step(known: np.ndarray) -> np.ndarray:
    """The root step ``(..., 3)`` (:data:`STEP_FEATURES`) that leads out of the last of the known poses
    ``(..., n, D)``: the step between the last two (zero with one known pose). Learned priors carry it per
    particle, because the newest frame's step is chosen by the sample that follows it."""
    known = np.atleast_2d(np.asarray(known, float))
    if known.shape[-2] < 2:
        return np.zeros(known.shape[:-2] + (len(STEP_FEATURES),))
    return poses_to_invariant(known[..., -2:, :])[..., -1, list(STEP_FEATURES)]


#: Ground speed (mm/frame) added before taking the log of a pace, so a standing person's pace stays finite.
PACE_FLOOR_MM = 2.0
#: The log pace of a person standing still, the least a pace can be.
STANDING_LOG_PACE = float(np.log(PACE_FLOOR_MM))


def log_pace(step: np.ndarray) -> np.ndarray:
    """The log pace ``log(PACE_FLOOR_MM + ground speed)`` of root steps ``(..., 2+)`` whose first two numbers are
    the forward and lateral step (mm/frame, :data:`ROOT_FEATURE_NAMES`)."""
    step = np.asarray(step, float)
    return np.log(PACE_FLOOR_MM + np.hypot(step[..., 0], step[..., 1]))


def clip_log_pace(poses: np.ndarray, window: int) -> np.ndarray:
    """Each frame's pace ``(T - 1,)`` of a clip ``T x D`` (one per frame that :func:`clip_features` keeps): the log
    of :data:`PACE_FLOOR_MM` plus the ground speed (mm/frame) averaged over ``window`` frames centred on the frame
    (fewer at the clip's ends). The label a pace-conditioned prior learns its gait speed from: it follows a
    start, a stop or a change of pace over about ``window`` frames, and not the speed's rise and fall within one
    stride."""
    feats = poses_to_invariant(np.asarray(poses, float))[:-1]
    speed = np.hypot(feats[:, 0], feats[:, 1])
    half = max(int(window), 1) // 2
    csum = np.concatenate([[0.0], np.cumsum(speed)])
    idx = np.arange(len(speed))
    lo, hi = np.maximum(idx - half, 0), np.minimum(idx + half + 1, len(speed))
    return np.log(PACE_FLOOR_MM + (csum[hi] - csum[lo]) / (hi - lo))


def step_rms(clips: Sequence[np.ndarray]) -> np.ndarray:
    """RMS frame-to-frame change ``(D,)`` over pose sequences (each ``T x D``, T >= 2): the random-walk scale
    of the hand-made priors and the one-step diffusion scale of the learned ones (mm or rad per frame)."""
    if not clips:
        raise InputError("no training clips to estimate the frame-to-frame scale from")
    steps = []
    for poses in clips:
        poses = np.asarray(poses, float)
        if poses.ndim != 2 or len(poses) < 2:
            raise InputError(f"training clips need at least 2 frames of poses (T x D), got {poses.shape}")
        steps.append(np.diff(poses, axis=0))
    if len({c.shape[1] for c in steps}) != 1:
        raise InputError("training clips have different numbers of pose parameters")
    return np.sqrt(np.mean(np.concatenate(steps) ** 2, axis=0))


def clip_features(clips: Sequence[np.ndarray], dof_names: Sequence[str],
                  normaliser: "FeatureNormaliser | None" = None) -> tuple[list[np.ndarray], "FeatureNormaliser"]:
    """Normalised invariant features of pose clips (one ``(T_i - 1) x K`` array per clip: each clip's last
    frame is dropped, its velocities only repeat the step before) and the normaliser (fitted on them unless
    given)."""
    feats = [poses_to_invariant(np.asarray(c, float))[:-1] for c in clips]
    if normaliser is None:
        normaliser = FeatureNormaliser.fit(feats, feature_names(dof_names))
    return [normaliser.transform(f) for f in feats], normaliser
