"""The edge + silhouette likelihood of Deutscher & Reid (Taylor 2009, Sec. 6.3.3), batched over P x V x K.

For every particle and view each cone is projected: points are sampled evenly
along its two occluding-contour lines (the rulings whose tangent plane
contains the camera centre, :func:`tracker.core.cones.contour_corners`) and on a
grid between them in the image. Contour points look up the edge map, grid
points the silhouette (nearest pixel; a point outside the image or behind the
camera reads 0; the cost maps carry a border of cost 1). Per view::

    edge cost = mean over contour points of (1 - edge)^2
    silhouette cost = mean over grid points of (1 - silhouette)^2

and the log-likelihood is ``-sharpness * sum over views (edge cost +
silhouette cost)``. The optional bidirectional term (for monocular tracking)
adds, per view, the fraction of a fixed sample of foreground pixels that no
projected cone covers, so a model that explains only part of the silhouette is
penalised too. Poses outside the model's joint limits get ``-inf``.

Shapes: poses ``P x D``; observations ``V x H x W``; the result ``(P,)``.

Registered as ``edge-silhouette``. :meth:`EdgeSilhouetteLikelihood.prepare`
derives a frame's silhouettes and edge maps (:mod:`likelihoods.observations`)
and its cost maps once; the returned :class:`PreparedFrame` scores pose batches.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from threadpoolctl import ThreadpoolController

from likelihoods.observations import DEFAULT_OBSERVATION, BackgroundPlate, ObservationConfig, Observations, observe
from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.cones import contour_corners
from tracker.core.errors import InputError
from tracker.core.kinematics import forward_kinematics
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.registry import LikelihoodContext, Option, register_likelihood


@dataclass(frozen=True)
class EdgeSilhouetteConfig:
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


class EdgeSilhouetteLikelihood(Likelihood):
    """Log-likelihood of body poses given one frame's images from the cameras of ``rig``."""

    name = "edge-silhouette"

    def __init__(self, model: BodyModel, rig: CameraRig, config: EdgeSilhouetteConfig = EdgeSilhouetteConfig(),
                 observation: ObservationConfig = DEFAULT_OBSERVATION):
        if config.n_along < 2 or config.n_across < 1 or not config.sharpness > 0:
            raise InputError(f"need n_along >= 2, n_across >= 1 and a positive sharpness, got {config}")
        self.model = model
        self.rig = rig
        self.config = config
        self.observation = observation
        self.centres = np.array([c.centre for c in rig.cameras])
        self.n_contour = 2 * config.n_along
        self.weights = _sample_weights(config.n_along, config.n_across)  # 4 x N
        self._plates: dict[int, BackgroundPlate] = {}  # per view: the last plate seen, prepared once

    def settings(self) -> dict:
        return {"sharpness": self.config.sharpness, "bidirectional": self.config.bidirectional}

    def prepare(self, frame: Frame) -> "PreparedFrame":
        """Silhouettes and edge maps of the frame's images (provided masks where the frame has them).

        A sequence hands the same background plate (array) with every frame: its statistics are derived
        once per view and kept while the plate stays the same object.
        """
        plates = None if frame.backgrounds is None else [self._plate(v, b) for v, b in enumerate(frame.backgrounds)]
        return self.prepare_observations(observe(list(frame.images), plates,
                                                 None if frame.masks is None else list(frame.masks),
                                                 self.observation))

    def _plate(self, view: int, background: np.ndarray | None) -> BackgroundPlate | None:
        if background is None:
            return None
        plate = self._plates.get(view)
        if plate is None or plate.image is not background:
            plate = self._plates[view] = BackgroundPlate.of(background, self.observation)
        return plate

    def prepare_observations(self, obs: Observations) -> "PreparedFrame":
        """The scorer for already derived observations (``V x H x W`` silhouettes and edge maps)."""
        V = len(self.rig)
        if obs.n_views != V:
            raise InputError(f"observations have {obs.n_views} views but the rig has {V} cameras")
        n_fg = self.config.n_foreground if self.config.bidirectional else 0
        return PreparedFrame(self, _CostMaps.of(obs, n_fg))

    def terms(self, poses: np.ndarray, maps: "_CostMaps") -> LikelihoodTerms:
        poses = np.asarray(poses, float)
        P, V = len(poses), len(self.rig)
        valid = self.model.within_limits(poses)
        edge = np.ones((P, V))
        sil = np.ones((P, V))
        cover = np.ones((P, V)) if self.config.bidirectional else None
        # Blocks of particles keep the intermediates in cache: 256 at a time measured 1.5x faster than all
        # 4000 at once (each block is still one batched pass over particles, views and points).
        with _serial_blas():
            for start in range(0, P, BLOCK):
                block = slice(start, start + BLOCK)
                ok = valid[block]
                if ok.any():
                    e, s, c = self._block_costs(poses[block][ok], maps)
                    edge[block][ok], sil[block][ok] = e, s
                    if cover is not None:
                        cover[block][ok] = c
        total = edge + sil + (cover if cover is not None else 0.0)
        ll = np.where(valid, -self.config.sharpness * total.sum(axis=1), -np.inf)
        return LikelihoodTerms(edge=edge, silhouette=sil, coverage=cover, log_likelihood=ll)

    def _block_costs(self, poses: np.ndarray, maps: "_CostMaps"):
        """Edge, silhouette and (optional) coverage costs ``p x V`` of poses within the limits.

        float32 from the camera frames on (sub-pixel error about 1e-4 px), components on the leading axis and
        the views next, so every step runs over long contiguous arrays ``V x p x S (x 4 or N)``.
        """
        fk = forward_kinematics(self.model, poses)
        rotations, origins = fk.segment_rotations()  # p S 3 3, p S 3
        axes, origins = self.rig.frames_in_cameras(rotations, origins, np.float32)  # 3 3 V p S, 3 V p S
        X, Y, Z = contour_corners(self.model, axes, origins)  # each V p S 4: line 0 proximal, distal; line 1
        u, v = self.rig.pixels(X, Y, Z)
        behind = np.any(Z <= 0, axis=-1)
        u[behind] = -1e6  # reads the border of the cost maps: cost 1
        v[behind] = -1e6
        # Every sample is a fixed affine combination of the 4 corners: contour points spaced evenly along
        # each projected line (a ruling projects to a straight segment; with lens distortion a sub-pixel
        # approximation on a limb), then the grid between the lines. One matrix product per coordinate.
        V, p, S = Z.shape[:3]
        flat = maps.flat_index(u.reshape(-1, 4) @ self.weights, v.reshape(-1, 4) @ self.weights)
        flat = flat.reshape(V, p, S, -1)
        nc = self.n_contour
        edge = maps.edge.take(flat[..., :nc]).reshape(V, p, -1).mean(axis=-1).T
        sil = maps.silhouette.take(flat[..., nc:]).reshape(V, p, -1).mean(axis=-1).T
        cover = _uncovered(u, v, maps.foreground) if self.config.bidirectional else None
        return edge, sil, cover


class PreparedFrame(FrameLikelihood):
    """The likelihood bound to one frame's cost maps."""

    def __init__(self, likelihood: EdgeSilhouetteLikelihood, maps: "_CostMaps"):
        self.likelihood = likelihood
        self.maps = maps

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        return self.likelihood.terms(poses, self.maps).log_likelihood

    def terms(self, poses: np.ndarray) -> LikelihoodTerms:
        """Per-particle, per-view costs and the log-likelihoods of poses ``P x D``."""
        return self.likelihood.terms(poses, self.maps)


def _sample_weights(n_along: int, n_across: int) -> np.ndarray:
    """Weights ``4 x N`` of the samples on the corners (line 0 proximal, distal, line 1 proximal, distal):
    ``2 n_along`` contour points, then ``n_across x n_along`` grid points."""
    s = np.linspace(0.0, 1.0, n_along)
    rows = [[1 - si, si, 0.0, 0.0] for si in s] + [[0.0, 0.0, 1 - si, si] for si in s]
    for t in np.arange(1, n_across + 1) / (n_across + 1):
        rows += [[(1 - t) * (1 - si), (1 - t) * si, t * (1 - si), t * si] for si in s]
    return np.array(rows, np.float32).T


#: Particles per block (see ``terms``).
BLOCK = 256


@lru_cache(maxsize=1)
def _blas() -> ThreadpoolController:
    return ThreadpoolController().select(user_api="blas")


def _serial_blas():
    """Context in which BLAS runs on one thread. The likelihood's matrix products are thin (``n x 4`` times
    ``4 x N``): a second BLAS thread gains about 25 us per product on an idle machine, and on a busy one,
    where BLAS threads wait for each other's cores, it measured 300 times slower (16 ms instead of 54 us).
    Parallel work goes to frames instead (the filter prepares them ahead in background threads)."""
    return _blas().limit(limits=1)

#: Border (pixels) of cost 1 around the cost maps, so that lookups need no bounds test.
PAD = 32


class _CostMaps:
    """Per-frame cost maps ``(1 - edge)^2`` and ``(1 - silhouette)^2``, padded with cost 1, flattened, and
    (for the bidirectional term) a fixed sample of foreground pixels per view."""

    def __init__(self, edge: np.ndarray, silhouette: np.ndarray, foreground: list[np.ndarray]):
        V, self.Hp, self.Wp = edge.shape
        self.foreground = foreground
        self.edge = edge.reshape(-1)
        self.silhouette = silhouette.reshape(-1)
        self.view_offset = np.arange(V, dtype=np.int32) * (self.Hp * self.Wp)

    @classmethod
    def of(cls, obs: Observations, n_foreground: int = 0) -> "_CostMaps":
        def padded(m: np.ndarray) -> np.ndarray:
            V, H, W = m.shape
            out = np.ones((V, H + 2 * PAD, W + 2 * PAD), np.float32)
            inner = out[:, PAD:PAD + H, PAD:PAD + W]
            np.square(np.subtract(1.0, m, out=inner), out=inner)
            return out
        fg = [foreground_sample(sil, n_foreground) for sil in obs.silhouettes] if n_foreground else []
        return cls(padded(obs.edges), padded(obs.silhouettes), fg)

    def flat_index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Flat indices of the nearest pixels to ``(x, y)``, each ``(V * n) x N`` float32 with views leading
        (clamped to the border)."""
        V = len(self.view_offset)
        ix = np.add(x, np.float32(PAD + 0.5), out=x)
        iy = np.add(y, np.float32(PAD + 0.5), out=y)
        ix = np.clip(ix, 0, self.Wp - 1, out=ix).astype(np.int32)
        iy = np.clip(iy, 0, self.Hp - 1, out=iy).astype(np.int32)
        iy *= self.Wp
        iy += ix
        per_view = iy.reshape(V, -1)
        per_view += self.view_offset[:, None]
        return iy


def foreground_sample(silhouette: np.ndarray, n: int) -> np.ndarray:
    """``n`` foreground pixels ``(x, y)`` spread evenly over the silhouette's pixels (deterministic)."""
    ys, xs = np.nonzero(silhouette > 0.5)
    if len(xs) == 0:
        return np.zeros((0, 2), np.float32)
    idx = np.linspace(0, len(xs) - 1, min(n, len(xs))).astype(int)
    return np.stack([xs[idx], ys[idx]], axis=1).astype(np.float32)


def _uncovered(u: np.ndarray, v: np.ndarray, foreground: list[np.ndarray]) -> np.ndarray:
    """Fraction ``p x V`` of the sampled foreground pixels (``F x 2`` per view) outside every projected cone (a
    cone's projection is taken as the quadrilateral of its contour lines' end points, pixel coordinates
    ``u``, ``v`` ``V x p x S x 4``)."""
    V, p = u.shape[:2]
    out = np.zeros((p, V))
    around = [0, 1, 3, 2]  # the quadrilateral's corners in order
    for view in range(V):  # views only; particles, segments and pixels are batched
        fg = foreground[view]
        if len(fg) == 0:
            continue
        qx, qy = u[view][..., around], v[view][..., around]  # p S 4
        ex, ey = np.roll(qx, -1, axis=2) - qx, np.roll(qy, -1, axis=2) - qy
        cross = ex[..., None] * (fg[:, 1] - qy[..., None]) - ey[..., None] * (fg[:, 0] - qx[..., None])  # p S 4 F
        inside = np.all(cross >= 0, axis=2) | np.all(cross <= 0, axis=2)  # p S F
        out[:, view] = 1.0 - inside.any(axis=1).mean(axis=1)
    return out


@register_likelihood(
    "edge-silhouette", summary="Deutscher & Reid's edge + silhouette likelihood, summed over views",
    options=(Option("sharpness", float, EdgeSilhouetteConfig.sharpness, "likelihood sharpness", minimum=0.0,
                    strict=True, maximum=1e6),
             Option("bidirectional", bool, False,
                    "also penalise foreground the model does not cover (for monocular tracking)")))
def build_edge_silhouette(context: LikelihoodContext, options: dict) -> EdgeSilhouetteLikelihood:
    config = EdgeSilhouetteConfig(sharpness=options["sharpness"], bidirectional=options["bidirectional"])
    return EdgeSilhouetteLikelihood(context.body_model, context.rig, config)
