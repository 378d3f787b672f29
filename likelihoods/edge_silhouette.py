"""The edge + silhouette likelihood of Deutscher & Reid (Taylor 2009, Sec. 6.3.3), batched over P x V x K.

For every particle and view each cone is projected: points are sampled evenly
along its two occluding-contour lines (the rulings whose tangent plane
contains the camera centre, :func:`tracker.cones.contour_angles`) and on a
grid between them in the image. Contour points look up the edge map, grid
points the silhouette (nearest pixel; a point outside the image or behind the
camera reads 0). Per view::

    edge cost = mean over contour points of (1 - edge)^2
    silhouette cost = mean over grid points of (1 - silhouette)^2

and the log-likelihood is ``-sharpness * sum over views (edge cost +
silhouette cost)``. The optional bidirectional term (for monocular tracking)
adds, per view, the fraction of a fixed sample of foreground pixels that no
projected cone covers, so a model that explains only part of the silhouette is
penalised too. Poses outside the model's joint limits get ``-inf``.

Shapes: poses ``P x D``; observations ``V x H x W``; the result ``(P,)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from likelihoods.observations import Observations
from tracker.body import BodyModel
from tracker.cameras import CameraRig
from tracker.cones import contour_angles, contour_endpoints
from tracker.kinematics import forward_kinematics


@dataclass(frozen=True)
class LikelihoodParams:
    """``n_along`` points per contour line, ``n_across`` grid lines between the two contour lines
    (at fractions ``1/(n+1) ... n/(n+1)`` of the way), ``sharpness`` multiplies the summed costs,
    ``bidirectional`` adds the uncovered-foreground term with ``n_foreground`` foreground pixels per view."""

    n_along: int = 6
    n_across: int = 3
    sharpness: float = 40.0
    bidirectional: bool = False
    n_foreground: int = 150


@dataclass
class LikelihoodTerms:
    """Per-particle, per-view costs ``P x V`` (each in [0, 1]) and the log-likelihoods ``(P,)``."""

    edge: np.ndarray
    silhouette: np.ndarray
    coverage: np.ndarray | None
    log_likelihood: np.ndarray


class EdgeSilhouetteLikelihood:
    """Log-likelihood of body poses given one frame's observations from the cameras of ``rig``."""

    def __init__(self, model: BodyModel, rig: CameraRig, params: LikelihoodParams = LikelihoodParams()):
        if params.n_along < 2 or params.n_across < 1 or params.sharpness <= 0:
            raise ValueError(f"need n_along >= 2, n_across >= 1 and a positive sharpness, got {params}")
        self.model = model
        self.rig = rig
        self.params = params
        self.centres = np.array([c.centre for c in rig.cameras])
        self.s = np.linspace(0.0, 1.0, params.n_along).astype(np.float32)
        self.across = (np.arange(1, params.n_across + 1) / (params.n_across + 1)).astype(np.float32)

    def __call__(self, poses: np.ndarray, obs: Observations) -> np.ndarray:
        return self.terms(poses, obs).log_likelihood

    def terms(self, poses: np.ndarray, obs: Observations) -> LikelihoodTerms:
        poses = np.asarray(poses, float)
        P, V = len(poses), len(self.rig)
        if obs.n_views != V:
            raise ValueError(f"observations have {obs.n_views} views but the rig has {V} cameras")
        H, W = obs.silhouettes.shape[1:]
        valid = self.model.within_limits(poses)
        edge = np.ones((P, V))
        sil = np.ones((P, V))
        cover = np.ones((P, V)) if self.params.bidirectional else None
        if valid.any():
            frames = forward_kinematics(self.model, poses[valid]).segment_frames()
            angles = contour_angles(self.model, frames, self.centres)  # p V S 2
            ends = contour_endpoints(self.model, frames, angles).astype(np.float32)  # p V S 2 2 3
            p, _, S = ends.shape[:3]
            end_pix, depth = self.rig.project_each(ends.reshape(p, V, S * 4, 3))
            end_pix = end_pix.reshape(p, V, S, 2, 2, 2)
            front = np.all(depth.reshape(p, V, S, 4) > 0, axis=-1)  # p V S: the whole cone in front
            # Contour samples: evenly spaced in the image along each projected line (a ruling projects to a
            # straight segment; with lens distortion this is a sub-pixel approximation on a limb).
            s_ = self.s[:, None]
            pix = end_pix[..., 0:1, :] * (1 - s_) + end_pix[..., 1:2, :] * s_  # p V S 2 K 2
            # Grid inside the projected cone: between the two contour lines, at the same axial fraction.
            a = self.across[:, None, None]  # T x 1 x 1
            grid = pix[:, :, :, None, 0] * (1 - a) + pix[:, :, :, None, 1] * a  # p V S T K 2
            K, T = len(self.s), len(self.across)
            in_front = np.broadcast_to(front[..., None, None], (p, V, S, 2, K))
            grid_front = np.broadcast_to(front[..., None, None], (p, V, S, T, K))
            e = _lookup(obs.edges, pix.reshape(p, V, -1, 2), in_front.reshape(p, V, -1))
            s_val = _lookup(obs.silhouettes, grid.reshape(p, V, -1, 2), grid_front.reshape(p, V, -1))
            edge[valid] = np.mean((1.0 - e) ** 2, axis=-1)
            sil[valid] = np.mean((1.0 - s_val) ** 2, axis=-1)
            if cover is not None:
                cover[valid] = _uncovered(pix, in_front, obs, self.params.n_foreground)
        total = edge + sil + (cover if cover is not None else 0.0)
        ll = np.where(valid, -self.params.sharpness * total.sum(axis=1), -np.inf)
        return LikelihoodTerms(edge=edge, silhouette=sil, coverage=cover, log_likelihood=ll)


def _lookup(maps: np.ndarray, pix: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Nearest-pixel values of ``maps`` ``V x H x W`` at ``pix`` ``p x V x N x 2``; 0 off-image or where not ok."""
    V, H, W = maps.shape
    ix = np.rint(pix[..., 0]).astype(np.int32)
    iy = np.rint(pix[..., 1]).astype(np.int32)
    inside = ok & (ix >= 0) & (ix < W) & (iy >= 0) & (iy < H)
    flat = (np.arange(V, dtype=np.int64)[:, None] * (H * W) + np.clip(iy, 0, H - 1) * W + np.clip(ix, 0, W - 1))
    vals = np.take(maps.reshape(-1), flat)
    return np.where(inside, vals, 0.0)


def foreground_sample(silhouette: np.ndarray, n: int) -> np.ndarray:
    """``n`` foreground pixels ``(x, y)`` spread evenly over the silhouette's pixels (deterministic)."""
    ys, xs = np.nonzero(silhouette > 0.5)
    if len(xs) == 0:
        return np.zeros((0, 2), np.float32)
    idx = np.linspace(0, len(xs) - 1, min(n, len(xs))).astype(int)
    return np.stack([xs[idx], ys[idx]], axis=1).astype(np.float32)


def _uncovered(pix: np.ndarray, in_front: np.ndarray, obs: Observations, n: int) -> np.ndarray:
    """Fraction ``p x V`` of sampled foreground pixels outside every projected cone (a cone's projection is
    taken as the quadrilateral of its contour lines' end points)."""
    p, V, S = pix.shape[:3]
    out = np.zeros((p, V))
    for v in range(V):  # views only; particles, segments and pixels are batched
        fg = foreground_sample(obs.silhouettes[v], n)
        if len(fg) == 0:
            continue
        quad = np.stack([pix[:, v, :, 0, 0], pix[:, v, :, 0, -1], pix[:, v, :, 1, -1], pix[:, v, :, 1, 0]],
                        axis=2)  # p S 4 2
        edge_vec = np.roll(quad, -1, axis=2) - quad
        rel = fg[None, None, None, :, :] - quad[:, :, :, None, :]  # p S 4 F 2
        cross = edge_vec[..., None, 0] * rel[..., 1] - edge_vec[..., None, 1] * rel[..., 0]  # p S 4 F
        inside = np.all(cross >= 0, axis=2) | np.all(cross <= 0, axis=2)  # p S F
        inside &= np.all(in_front[:, v], axis=(2, 3))[:, :, None]
        out[:, v] = 1.0 - inside.any(axis=1).mean(axis=1)
    return out
