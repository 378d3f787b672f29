"""Retargeting: turn a mocap clip into poses of the 15-cone body model.

1. The subject's shape comes from the clip's own joints (:func:`shape_from_points`):
   each segment length is the median distance between the two joints it joins;
   hip and shoulder offsets from the median hip / shoulder widths; radii are the
   default adult's, scaled by stature.
2. Poses are fitted per frame (:func:`fit_poses`) by projected
   Levenberg-Marquardt, all frames at once as one batch: minimise the squared
   distances between the model's 15 markers plus hand and toe ends and the
   mocap's, with a weak pull of joint angles toward zero (1 mm per radian; 20
   for the elbow twists) that only decides dofs the points cannot see (twist of
   the head about its own axis, for example). Poses are kept inside the joint limits. Frames whose fit
   is worse than their neighbour's are refitted starting from the neighbour, and frames still fitted badly
   (an arm raised above the shoulder, whose fit from the rest pose stops at the shoulder's limits) are restarted
   from a grid of shoulder angles.
3. The ground-truth markers are the mocap's own joints, not the refitted model's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from data_tools.motion.mocap import MocapClip, frame_times, marker_positions
from tracker.core.body import (
    DEFAULT_STATURE, EXTRA_POINT_NAMES, MARKER_NAMES, SEGMENT_NAMES, BodyModel, BodyShape, default_shape,
    fifteen_cone_model,
)
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics, point_jacobians
from tracker.core.rotations import continuous_exp_maps, elementary_rotation, matrix_to_exp_map
from tracker.core.timewarp import exp_map_triples, sample_clip

FIT_POINTS = MARKER_NAMES + EXTRA_POINT_NAMES
_P = {name: i for i, name in enumerate(FIT_POINTS)}

#: Weight of each fitted point (extra points help with hand and foot angles only).
_POINT_WEIGHTS = np.array([1.0] * len(MARKER_NAMES) + [0.5] * len(EXTRA_POINT_NAMES))
#: Pull of joint angles toward zero, in mm of residual per radian. The elbow
#: twists are seen only through the small, noisy deviation of the hand from the
#: forearm line, so they are held more firmly.
_ANGLE_PRIOR_MM_PER_RAD = 1.0
_TWIST_PRIOR_MM_PER_RAD = 20.0


def _angle_prior_weights(model: BodyModel) -> np.ndarray:
    w = np.full(model.n_dofs - 6, _ANGLE_PRIOR_MM_PER_RAD)
    for side in ("left", "right"):
        w[model.dof_index(f"{side}_elbow_twist") - 6] = _TWIST_PRIOR_MM_PER_RAD
    return w


@dataclass
class RetargetResult:
    """A clip as body-model poses. Arrays have T frames on the leading axis; mm."""

    model: BodyModel
    poses: np.ndarray  # T x 40
    markers: np.ndarray  # T x 15 x 3, the mocap's joints (ground truth)
    model_markers: np.ndarray  # T x 15 x 3, the model's markers at the fitted poses
    fps: float
    source: str

    @property
    def residual_per_frame(self) -> np.ndarray:
        """Mean distance (mm) over the 15 markers between model and mocap, per frame."""
        return np.linalg.norm(self.model_markers - self.markers, axis=-1).mean(axis=-1)

    @property
    def mean_residual(self) -> float:
        return float(self.residual_per_frame.mean())


def _median_dist(points: np.ndarray, a: str, b: str) -> float:
    return float(np.median(np.linalg.norm(points[:, _P[a]] - points[:, _P[b]], axis=-1)))


def _pelvis_frames(points: np.ndarray) -> np.ndarray:
    """Per-frame pelvis axes ``T x 3 x 3`` (columns x, y, z) from the root and hip joints.

    y runs along the hip line (right to left); z is perpendicular to it, in the
    plane of root and hips turned about y by one fixed angle (per clip) that
    aligns it with the median root-to-thorax direction; x = y cross z.
    """
    y = points[:, _P["left_hip"]] - points[:, _P["right_hip"]]
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    rel = points[:, _P["pelvis"]] - points[:, _P["left_hip"]]
    z = rel - np.sum(rel * y, axis=-1, keepdims=True) * y
    up = points[:, _P["thorax"]] - points[:, _P["pelvis"]]
    norm = np.linalg.norm(z, axis=-1, keepdims=True)
    # Root on the hip line: fall back to the thorax direction.
    z = np.where(norm > 1.0, z / np.maximum(norm, 1e-12), up - np.sum(up * y, axis=-1, keepdims=True) * y)
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    z *= np.sign(np.sum(z * up, axis=-1, keepdims=True) + 1e-12)
    frames = np.stack([np.cross(y, z), y, z], axis=-1)
    # Pitch about the hip line so that z follows the median root-to-thorax
    # direction: the rest pose is then an upright stance with a straight spine,
    # and hip angles mean what the joint limits assume.
    u = np.median(np.einsum("tji,tj->ti", frames, up), axis=0)
    phi = np.arctan2(u[0], u[2])
    return frames @ elementary_rotation("y", phi)


def shape_from_points(points: np.ndarray, source: str | None = None) -> BodyShape:
    """Body shape from fit points ``T x 19 x 3`` (mm; :data:`FIT_POINTS` order).

    Hip offsets are exact in the pelvis frame of :func:`_pelvis_frames`, and
    shoulder offsets are measured in a torso frame (z from the abdomen joint to
    the thorax, y along the shoulder line); both are medians over frames. The abdomen joint sits on the pelvis z axis at the
    height that keeps the abdomen-to-thorax distance most nearly constant over
    the clip, so that bending the one abdomen joint can follow a bending spine.
    Radii come from the default shape scaled by the ratio of this subject's
    stature to the default's (mocap skeletons carry no widths).
    """
    base = default_shape()
    frames = _pelvis_frames(points)
    root = points[:, _P["pelvis"]]

    def in_pelvis(name: str) -> np.ndarray:
        return np.median(np.einsum("tji,tj->ti", frames, points[:, _P[name]] - root), axis=0)

    thorax = points[:, _P["thorax"]]
    heights = np.linspace(-0.2, 0.6, 81) * _median_dist(points, "pelvis", "thorax")
    spread = [np.std(np.linalg.norm(thorax - root - h * frames[:, :, 2], axis=-1)) for h in heights]
    # One frame cannot show where the spine bends: keep the default shape's abdomen joint, at the pelvis origin.
    h_abd = float(heights[int(np.argmin(spread))]) if len(points) > 1 else 0.0
    L = {}
    L["torso"] = float(np.median(np.linalg.norm(thorax - root - h_abd * frames[:, :, 2], axis=-1)))
    L["head"] = _median_dist(points, "thorax", "head")
    for side in ("left", "right"):
        L[f"{side}_upper_arm"] = _median_dist(points, f"{side}_shoulder", f"{side}_elbow")
        L[f"{side}_lower_arm"] = _median_dist(points, f"{side}_elbow", f"{side}_wrist")
        L[f"{side}_hand"] = _median_dist(points, f"{side}_wrist", f"{side}_hand_end")
        L[f"{side}_upper_leg"] = _median_dist(points, f"{side}_hip", f"{side}_knee")
        L[f"{side}_lower_leg"] = _median_dist(points, f"{side}_knee", f"{side}_ankle")
        L[f"{side}_foot"] = _median_dist(points, f"{side}_ankle", f"{side}_toe")
    # Torso frames: z from the abdomen joint to the thorax, y along the shoulder line.
    abd = root + h_abd * frames[:, :, 2]
    tz = thorax - abd
    tz /= np.linalg.norm(tz, axis=-1, keepdims=True)
    ty = points[:, _P["left_shoulder"]] - points[:, _P["right_shoulder"]]
    ty -= np.sum(ty * tz, axis=-1, keepdims=True) * tz
    ty /= np.linalg.norm(ty, axis=-1, keepdims=True)
    torso_frames = np.stack([np.cross(ty, tz), ty, tz], axis=-1)
    offsets = {}
    for side in ("left", "right"):
        hip = in_pelvis(f"{side}_hip")
        offsets[f"{side}_hip_offset"] = tuple(float(x) for x in hip)
        sh = np.median(np.einsum("tji,tj->ti", torso_frames, points[:, _P[f"{side}_shoulder"]] - thorax), axis=0)
        offsets[f"{side}_shoulder_offset"] = tuple(float(x) for x in sh)
    sh_half = 0.5 * _median_dist(points, "left_shoulder", "right_shoulder")
    L["pelvis"] = float(max(-offsets["left_hip_offset"][2], -offsets["right_hip_offset"][2], 0.5 * sh_half))
    for name, value in L.items():
        if not np.isfinite(value) or value < 1.0:
            raise InputError(f"skeleton gives segment {name} a length of {value:.3g} mm: joints coincide", source)
    stature = (L["head"] + L["torso"] + h_abd - 0.5 * (offsets["left_hip_offset"][2] + offsets["right_hip_offset"][2])
               + 0.5 * (L["left_upper_leg"] + L["right_upper_leg"] + L["left_lower_leg"] + L["right_lower_leg"])
               + 0.04 * DEFAULT_STATURE)
    shape = base.scaled_radii(stature / DEFAULT_STATURE)
    shape.lengths = {s: float(L[s]) for s in SEGMENT_NAMES}
    shape.abdomen_offset = (0.0, 0.0, h_abd)
    for k, v in offsets.items():
        setattr(shape, k, tuple(float(x) for x in v))
    return shape.validate(source)


def _root_from_points(points: np.ndarray) -> np.ndarray:
    """Initial root (position, exp map) ``T x 6`` from the pelvis frames of the root and hips."""
    return np.concatenate([points[:, _P["pelvis"]], matrix_to_exp_map(_pelvis_frames(points))], axis=-1)


def _residuals(model: BodyModel, poses: np.ndarray, targets: np.ndarray, point_idx: np.ndarray,
               prior_w: np.ndarray, jacobian: bool = False):
    """Weighted point residuals and the angle prior ``T x R`` (and their Jacobian ``T x R x D``)."""
    fk = forward_kinematics(model, poses)
    pts = fk.points[..., point_idx, :]
    T = poses.shape[0]
    r_pts = ((pts - targets) * _POINT_WEIGHTS[:, None]).reshape(T, -1)
    r = np.concatenate([r_pts, prior_w * poses[:, 6:]], axis=-1)
    if not jacobian:
        return r
    Jp = point_jacobians(model, poses, fk)[:, point_idx] * _POINT_WEIGHTS[:, None, None]
    D = poses.shape[1]
    Jprior = np.zeros((D - 6, D))
    Jprior[:, 6:] = np.diag(prior_w)
    J = np.concatenate([Jp.reshape(T, -1, D), np.broadcast_to(Jprior, (T, D - 6, D))], axis=1)
    return r, J


def fit_poses(model: BodyModel, targets: np.ndarray, init: np.ndarray, iterations: int = 40) -> tuple[np.ndarray,
                                                                                                      np.ndarray]:
    """Projected Levenberg-Marquardt, one independent problem per frame, batched.

    ``targets`` ``T x 19 x 3`` (mm, :data:`FIT_POINTS`), ``init`` ``T x 40``.
    Returns the poses ``T x 40`` (inside the limits) and each frame's final
    cost (sum of squared residuals, mm^2). Jacobians are analytic
    (:func:`tracker.core.kinematics.point_jacobians`).
    """
    point_idx = np.array([model.point_index(n) for n in FIT_POINTS])
    T, D = init.shape
    q = model.clip_to_limits(init)
    prior_w = _angle_prior_weights(model)
    r = _residuals(model, q, targets, point_idx, prior_w)
    cost = np.einsum("tr,tr->t", r, r)
    mu = np.full(T, 1e-3)
    eye = np.eye(D)
    active = np.ones(T, bool)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        qa = q[idx]
        ra, J = _residuals(model, qa, targets[idx], point_idx, prior_w, jacobian=True)
        JtJ = np.swapaxes(J, 1, 2) @ J
        g = np.einsum("nrd,nr->nd", J, ra)
        A = JtJ + mu[idx, None, None] * (eye * np.diagonal(JtJ, axis1=1, axis2=2)[:, None, :] + 1e-9 * eye)
        step = -np.linalg.solve(A, g[..., None])[..., 0]
        q_new = model.clip_to_limits(qa + step)
        r_new = _residuals(model, q_new, targets[idx], point_idx, prior_w)
        c_new = np.einsum("tr,tr->t", r_new, r_new)
        better = c_new < cost[idx]
        gain = (cost[idx] - c_new) / np.maximum(cost[idx], 1e-12)
        acc = idx[better]
        q[acc], r[acc], cost[acc] = q_new[better], r_new[better], c_new[better]
        mu[idx] = np.where(better, np.maximum(mu[idx] / 3.0, 1e-9), np.minimum(mu[idx] * 4.0, 1e8))
        done = (better & (gain < 1e-10)) | (mu[idx] >= 1e8) | (np.abs(step).max(axis=1) < 1e-9)
        active[idx[done]] = False
    return q, cost


def retarget(clip: MocapClip, fps: float | None = None, shape: BodyShape | None = None) -> RetargetResult:
    """Fit the 15-cone model to a mocap clip, at ``fps`` Hz (None: the clip's own rate).

    At another rate the clip is sampled at the times :func:`~data_tools.motion.mocap.frame_times` gives: frames
    that fall on the source's are fitted as they are (120 to 60 Hz fits every second frame); between two
    source frames both are fitted and the poses interpolated as the time warp does
    (:func:`tracker.core.timewarp.sample_clip`: slerp for the root's and ball joints' rotations, linear for
    the rest), the ground-truth markers linearly. Only the source frames a sample reads are fitted. The shape
    is estimated from the fitted frames unless given. Root orientations are made continuous over time (no
    jumps of 2 pi in the exp map).
    """
    if clip.n_frames < 1:
        raise InputError("clip has no frames", clip.path)
    times = frame_times(clip.n_frames, clip.fps, clip.fps if fps is None else fps, clip.path)
    whole = np.all(times == np.round(times))
    lo = np.minimum(np.floor(times).astype(int), max(clip.n_frames - 2, 0))
    read = times.astype(int) if whole else np.unique(np.concatenate([lo[times - lo < 1], lo[times > lo] + 1]))
    all_points = marker_positions(clip, FIT_POINTS)
    if not np.all(np.isfinite(all_points)):
        raise InputError("joint positions contain NaN or infinite values", clip.path)
    points = all_points[read]
    shape = shape or shape_from_points(points, clip.path)
    model = fifteen_cone_model(shape)
    poses = _fit_frames(model, points)
    markers = points[:, :len(MARKER_NAMES)]
    if not whole:
        poses = sample_clip(_fill(clip.n_frames, read, poses), times, exp_map_triples(model))
        poses[:, 3:6] = continuous_exp_maps(poses[:, 3:6])
        flat = all_points[:, :len(MARKER_NAMES)].reshape(clip.n_frames, -1)
        markers = sample_clip(flat, times, ()).reshape(len(times), len(MARKER_NAMES), 3)
    fps = clip.fps if fps is None else float(fps)
    model_markers = forward_kinematics(model, poses).markers
    return RetargetResult(model, poses, markers, model_markers, fps, clip.path)


def _fill(n_frames: int, read: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """The clip's ``n_frames`` poses (``T x D``): the fitted ``poses`` at the frames ``read`` and, at every
    other frame (one no sample reads with any weight), a copy of the next fitted frame's (the last one's after
    it), so that every number is finite."""
    return poses[np.minimum(np.searchsorted(read, np.arange(n_frames)), len(read) - 1)]


def _fit_frames(model: BodyModel, points: np.ndarray) -> np.ndarray:
    """Poses ``T x 40`` fitted to the fit points ``T x 19 x 3`` (frames in time order), refitted from their
    neighbours' solutions where that does better, frames still fitted badly restarted with the arms raised
    (:func:`_restart_arms`), root orientations continuous."""
    init = np.zeros((len(points), model.n_dofs))
    init[:, :6] = _root_from_points(points)
    poses, cost = fit_poses(model, points, init)
    _refit_from_neighbours(model, points, poses, cost)
    # Restart every few badly fitted frames, let their neighbours start from them, then the rest still bad.
    for stride in (_ARM_STRIDE, 1):
        if _restart_arms(model, points, poses, cost, stride):
            _refit_from_neighbours(model, points, poses, cost, only_bad=True)
    poses[:, 3:6] = continuous_exp_maps(poses[:, 3:6])
    return poses


def _refit_from_neighbours(model: BodyModel, points: np.ndarray, poses: np.ndarray, cost: np.ndarray,
                           only_bad: bool = False) -> None:
    """Refit every frame (``only_bad``: every frame fitted worse than :data:`ARM_RESTART_MM`) from its neighbours'
    solutions, keeping what does better (escapes the occasional local minimum of the rest-pose start); ``poses``
    ``T x D`` and ``cost`` ``(T,)`` updated in place."""
    for _ in range(3):
        improved = False
        for shift in (1, -1):
            rows = _badly_fitted(cost) if only_bad else np.arange(len(poses))
            if rows.size == 0:
                return
            start = np.roll(poses, shift, axis=0)
            start[0 if shift == 1 else -1] = poses[0 if shift == 1 else -1]
            cand, c2 = fit_poses(model, points[rows], start[rows], iterations=15)
            better = _improves(c2, cost[rows])
            if better.any():
                improved = True
                poses[rows[better]], cost[rows[better]] = cand[better], c2[better]
        if not improved:
            break


def _improves(new_cost: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Where a refit's cost is lower than the fit's by more than rounding (both ``(F,)``, mm^2)."""
    return new_cost < cost * (1 - 1e-6) - 1e-6


def _badly_fitted(cost: np.ndarray) -> np.ndarray:
    """The frames whose fit is worse than :data:`ARM_RESTART_MM` (indices)."""
    return np.flatnonzero(np.sqrt(cost / len(FIT_POINTS)) > ARM_RESTART_MM)


#: A frame whose fit stays worse than this (mm; ``sqrt(cost / 19)``, the root-mean-square of the weighted residuals
#: over the 19 fit points, the angle pull included) is restarted with the arms raised (:func:`_restart_arms`): a
#: well-read frame scores 1-3 mm by it (07_01: median 1.9), and an arm raised above the shoulder from the rest
#: pose's start ends in a local minimum with the shoulder at its joint limits, tens of mm off.
ARM_RESTART_MM = 5.0
#: Starting values per shoulder angle for :func:`_restart_arms`: this many, evenly spread inside the joint's limits.
_ARM_START_VALUES = 3
#: Iterations from every start before the most promising starts of each frame (this many) are fitted fully.
_ARM_SCREEN_ITERATIONS, _ARM_KEPT_STARTS = 8, 3
#: Frames restarted in one batch (each takes about 3.5 MB for its 27 starts).
_ARM_BATCH = 64
#: The first restarts take every this many badly fitted frames; their neighbours start from them.
_ARM_STRIDE = 4


def _restart_arms(model: BodyModel, points: np.ndarray, poses: np.ndarray, cost: np.ndarray, stride: int = 1) -> bool:
    """Refit the frames fitted worse than :data:`ARM_RESTART_MM` from the root alone (every joint angle zero) with
    one shoulder, then the other, started at each point of a grid inside its limits (``3^3`` starts per
    shoulder); keep the best fit where it does better. ``poses`` ``T x D`` and ``cost`` ``(T,)`` updated in
    place; returns whether a frame improved. A model without a shoulder's three angles is left as it is."""
    bad = _badly_fitted(cost)[::stride]
    names = list(model.dof_names)
    improved = False
    for side in ("left", "right"):
        axes = [f"{side}_shoulder_{axis}" for axis in "xyz"]
        if bad.size == 0 or not all(a in names for a in axes):
            continue
        index = [names.index(a) for a in axes]
        margin = 0.1  # rad, inside the limits
        grid = np.stack(np.meshgrid(*[np.linspace(model.lower[i] + margin, model.upper[i] - margin, _ARM_START_VALUES)
                                      for i in index], indexing="ij"), axis=-1).reshape(-1, 3)
        for first in range(0, bad.size, _ARM_BATCH):
            frames = bad[first:first + _ARM_BATCH]
            chosen, chosen_cost = _best_restart(model, points[frames], poses[frames, :6], index, grid)
            better = _improves(chosen_cost, cost[frames])
            if better.any():
                improved = True
                poses[frames[better]], cost[frames[better]] = chosen[better], chosen_cost[better]
    return improved


def _best_restart(model: BodyModel, points: np.ndarray, roots: np.ndarray, index: list[int],
                  grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each frame's best fit (poses ``F x D``, costs ``(F,)``) to its fit points ``F x 19 x 3`` from its root
    ``F x 6`` with the joint angles ``index`` started at each row of ``grid`` ``S x 3`` and the others at zero: a
    few iterations from every start pick the most promising ones, which are then fitted fully."""
    n, S = len(points), len(grid)
    starts = np.zeros((n, S, model.n_dofs))
    starts[:, :, :6] = roots[:, None]
    starts[:, :, index] = grid
    fitted, fitted_cost = fit_poses(model, np.repeat(points, S, axis=0), starts.reshape(-1, model.n_dofs),
                                    iterations=_ARM_SCREEN_ITERATIONS)
    keep = min(_ARM_KEPT_STARTS, S)
    best = np.argsort(fitted_cost.reshape(n, S), axis=1)[:, :keep]
    polished, polished_cost = fit_poses(model, np.repeat(points, keep, axis=0),
                                        fitted.reshape(n, S, -1)[np.arange(n)[:, None], best].reshape(-1, model.n_dofs))
    which = polished_cost.reshape(n, keep).argmin(axis=1)
    return polished.reshape(n, keep, -1)[np.arange(n), which], polished_cost.reshape(n, keep)[np.arange(n), which]
