"""The edge + silhouette likelihood of Deutscher & Reid (Taylor 2009, Sec. 6.3.3), batched over P x V x K.

For every particle and view each cone is projected: points are sampled evenly
along its two occluding-contour lines (the rulings whose tangent plane
contains the camera centre, :func:`tracker.core.cones.contour_corners`) and on a
grid between them in the image. Contour points look up the edge map, grid
points the silhouette (nearest pixel; a point outside the image, and every
point of a cone with a corner behind the camera, costs 1). Per view::

    edge cost = mean over contour points of (1 - edge)^2
    silhouette cost = mean over grid points of (1 - silhouette)^2

and the log-likelihood is ``-sharpness * sum over views (edge cost +
silhouette cost)``. Poses outside the model's joint limits get ``-inf``.

The silhouette cost is one-directional: a body drawn smaller than the person, farther along a camera's ray,
lies inside the silhouette at little cost, and with one camera the estimate drifts away along the ray. The
bidirectional term adds, per view, the fraction of a fixed sample of foreground pixels that no projected cone
covers (``coverage``), so that a model that explains only part of the silhouette is penalised too. A cone's
projection is its whole outline, the quadrilateral between its contour lines and the images of its two end
ellipses (:func:`tracker.core.cones.end_ellipse_points`), and the sample keeps ``FOREGROUND_MARGIN`` pixels
inside the silhouette's outline: with the quadrilaterals alone and no margin the true pose left 11-18% of the
sample uncovered (synthetic walks), and a larger, nearer body scored better. Now a body moved along a camera's
ray scores highest at its true depth.

Shapes: poses ``P x D``; observations ``V x H x W``; the result ``(P,)``.

Registered as ``edge-silhouette``. :meth:`EdgeSilhouetteLikelihood.prepare`
derives a frame's silhouettes and edge maps (:mod:`likelihoods.observations`)
and its cost maps once; the returned :class:`PreparedFrame` scores pose batches.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from likelihoods.ground_contact import GROUND_OPTIONS, GroundContact, ground_contact_config
from tracker.core.arrays import device as device_of, is_cpu, namespace, torch_device
from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.cones import contour_corners, end_ellipse_points
from tracker.core.errors import InputError
from tracker.core.workers import share
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood, SumOfLikelihoods
from tracker.engine.registry import LikelihoodContext, Option, register_likelihood

if TYPE_CHECKING:  # the image code (OpenCV, numba) loads when a likelihood is built, not when it registers
    from likelihoods.observations import BackgroundPlate, ObservationConfig, Observations


@dataclass(frozen=True)
class EdgeSilhouetteConfig:
    """``n_along`` points per contour line, ``n_across`` grid lines between the two contour lines
    (at fractions ``1/(n+1) ... n/(n+1)`` of the way), ``sharpness`` multiplies the summed costs,
    ``bidirectional`` adds the uncovered-foreground term with ``n_foreground`` foreground pixels per view (off:
    Deutscher & Reid's one-directional silhouette cost alone)."""

    n_along: int = 6
    n_across: int = 3
    sharpness: float = 40.0
    bidirectional: bool = True
    n_foreground: int = 150


@dataclass
class LikelihoodTerms:
    """Per-particle, per-view costs ``P x V`` (each in [0, 1]) and the log-likelihoods ``(P,)``."""

    edge: np.ndarray
    silhouette: np.ndarray
    coverage: np.ndarray | None
    log_likelihood: np.ndarray


class EdgeSilhouetteLikelihood(Likelihood):
    """Log-likelihood of body poses given one frame's images from the cameras of ``rig``.

    ``device`` None (the default) scores on the CPU with one compiled loop
    (:mod:`likelihoods.compiled_costs`), the faster path there; a torch device (``"cuda"``, ``"cuda:N"``, or
    ``"cpu"`` to run the torch path on the CPU, as the tests do) scores with torch tensors on it
    (:meth:`array_costs`). The registered builder maps the run's device ``cpu`` to None (``--device``,
    ``track(device=...)``), so ``cpu`` means the compiled path there. ``threads`` (the CPU path): how many threads
    score a batch of poses, one block of particles at a time each; 1 when built directly, the run's threads
    (``--threads``, :func:`tracker.set_threads`, default the available cores) when built by
    ``tracker.build_likelihood`` or ``track``, fixed when built (assign ``threads`` to change it).
    ``observation`` (None: :data:`likelihoods.observations.DEFAULT_OBSERVATION`) derives a frame's silhouettes and
    edge maps.
    """

    name = "edge-silhouette"

    def __init__(self, model: BodyModel, rig: CameraRig, config: EdgeSilhouetteConfig = EdgeSilhouetteConfig(),
                 observation: ObservationConfig | None = None, device: str | None = None, threads: int = 1):
        from likelihoods.observations import DEFAULT_OBSERVATION

        if config.n_along < 2 or config.n_across < 1 or not config.sharpness > 0:
            raise InputError(f"need n_along >= 2, n_across >= 1 and a positive sharpness, got {config}")
        self.threads = threads
        self.device = None if device is None else torch_device(device)
        self.model = model
        self.rig = rig
        self.config = config
        self.observation = DEFAULT_OBSERVATION if observation is None else observation
        self.centres = np.array([c.centre for c in rig.cameras])
        self.n_contour = 2 * config.n_along
        self.weights = _sample_weights(config.n_along, config.n_across)  # 4 x N
        self._plates: dict[int, BackgroundPlate] = {}  # per view: the last plate seen, prepared once
        self._cone_tables = None

    @property
    def threads(self) -> int:
        """Threads that score a batch of poses on the CPU path (the calling one and ``threads - 1`` helpers)."""
        return self._threads

    @threads.setter
    def threads(self, threads: int) -> None:
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise InputError(f"threads must be an integer of at least 1, got {threads!r}")
        self._threads = int(threads)

    def settings(self) -> dict:
        out = {"sharpness": self.config.sharpness, "bidirectional": self.config.bidirectional}
        return out if self.device is None else {**out, "device": str(self.device)}

    def prepare(self, frame: Frame) -> "PreparedFrame":
        """Silhouettes and edge maps of the frame's images (provided masks where the frame has them).

        A sequence hands the same background plate (array) with every frame: its statistics are derived
        once per view and kept while the plate stays the same object.
        """
        from likelihoods.observations import observe

        bare = [v for v in range(frame.n_views) if (frame.masks is None or frame.masks[v] is None)
                and (frame.backgrounds is None or frame.backgrounds[v] is None)]
        if bare:  # (a sequence with keypoints hands out frames without either)
            raise InputError(f"frame {frame.index}, view(s) {', '.join(map(str, bare))}: neither a foreground mask "
                             f"nor a background plate, one of which the {self.name} likelihood needs: write masks "
                             "first (pose-tracker silhouettes SEQ), or track with --likelihood keypoints")
        plates = None if frame.backgrounds is None else [self._plate(v, b) for v, b in enumerate(frame.backgrounds)]
        return self.prepare_observations(observe(list(frame.images), plates,
                                                 None if frame.masks is None else list(frame.masks),
                                                 self.observation, self.threads))

    def _plate(self, view: int, background: np.ndarray | None) -> BackgroundPlate | None:
        from likelihoods.observations import BackgroundPlate

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
        maps = _CostMaps.of(obs, n_fg, self.threads)
        return PreparedFrame(self, maps if self.device is None else maps.to(self.device))

    def terms(self, poses: np.ndarray, maps: "_CostMaps") -> LikelihoodTerms:
        shape = np.shape(poses)
        if len(shape) != 2 or shape[1] != self.model.n_dofs:
            raise InputError(f"poses must be P x {self.model.n_dofs} for the {self.model.name} model, got {shape}")
        if self.device is not None:
            return self._device_terms(poses, maps)
        poses = np.asarray(poses, float)
        P, V = len(poses), len(self.rig)
        valid = self.model.within_limits(poses)
        edge = np.ones((P, V))
        sil = np.ones((P, V))
        cover = np.ones((P, V)) if self.config.bidirectional else None

        def score(block: slice) -> None:
            ok = valid[block]
            if ok.any():
                e, s, c = self._compiled_block_costs(poses[block][ok], maps)
                edge[block][ok], sil[block][ok] = e, s
                if cover is not None:
                    cover[block][ok] = c

        # This thread and threads - 1 helpers take blocks of particles in turn; the compiled kinematics and
        # costs run without the interpreter lock, so the threads score in parallel. Two blocks a thread
        # balance the load; more would hand the lock back and forth for nothing.
        block = min(MAX_BLOCK, max(MIN_BLOCK, -(-P // (2 * self.threads))))
        if self.config.bidirectional:
            block = min(block, BLOCK_BIDIRECTIONAL)
        blocks = [slice(start, start + block) for start in range(0, P, block)]
        share(score, blocks, self.threads)
        return self._combine(valid, edge, sil, cover)

    def _compiled_block_costs(self, poses: np.ndarray, maps: "_CostMaps"):
        """Edge, silhouette and (optional) coverage costs ``p x V`` of poses ``p x D`` within the limits: the CPU
        path, the compiled kinematics and :func:`likelihoods.compiled_costs.cone_costs`, in float64."""
        from likelihoods.compiled_costs import cone_costs, uncovered_fraction
        from tracker.core.kinematics import forward_kinematics

        p, V = len(poses), len(self.rig)
        edge, sil = np.empty((p, V)), np.empty((p, V))
        corners = ellipses = None
        if self.config.bidirectional:
            S = len(self.model.segments)
            corners = (np.empty((V, p, S, 4)), np.empty((V, p, S, 4)))
            ellipses = (np.empty((V, p, S, 6)), np.empty((V, p, S, 6)))
        cone_costs(forward_kinematics(self.model, poses), self._tables(), maps.edge, maps.silhouette,
                   maps.view_offset, maps.height, maps.width, self.n_contour, edge, sil, corners, ellipses)
        cover = None
        if corners is not None:
            cover = np.empty((p, V))
            uncovered_fraction(*corners, *ellipses, maps.foreground, cover)
        return edge, sil, cover

    def _tables(self):
        """The compiled loop's tables of this model, rig and sample pattern (made on first use)."""
        if self._cone_tables is None:
            from likelihoods.compiled_costs import ConeCostTables

            self._cone_tables = ConeCostTables.of(self.model, self.rig, self.weights)
        return self._cone_tables

    def _combine(self, valid, edge, sil, cover) -> LikelihoodTerms:
        """The terms from costs ``P x V`` (numpy arrays or tensors; 1 where a pose is outside the limits)."""
        xp = namespace(edge)
        total = edge + sil + (cover if cover is not None else 0.0)
        ll = xp.where(valid, -self.config.sharpness * xp.sum(total, axis=1), -float("inf"))
        return LikelihoodTerms(edge=edge, silhouette=sil, coverage=cover, log_likelihood=ll)

    def _device_terms(self, poses: np.ndarray, maps: "_CostMaps") -> LikelihoodTerms:
        """:meth:`terms` on the device: every pose scored in blocks of :data:`DEVICE_BLOCK` (poses outside the
        limits, or not finite, as the model's rest pose, then masked, so nothing is gathered on the host), one
        copy in and one out."""
        import torch

        P, V = len(poses), len(self.rig)
        if P == 0:
            empty = np.ones((0, V))
            return LikelihoodTerms(empty, empty.copy(), empty.copy() if self.config.bidirectional else None,
                                   np.zeros(0))
        block = DEVICE_BLOCK_BIDIRECTIONAL if self.config.bidirectional else DEVICE_BLOCK
        with torch.no_grad():
            x = torch.as_tensor(np.asarray(poses, float)).to(self.device, non_blocking=True)
            valid = self.model.within_limits(x)
            x = torch.where(valid[:, None], x, torch.as_tensor(self.model.rest_pose(), device=self.device))
            parts = [self.array_costs(x[i:i + block], maps) for i in range(0, P, block)]
            edge, sil, cover = (None if part[0] is None else torch.where(valid[:, None], torch.cat(part), 1.0)
                                for part in zip(*parts))
            terms = self._combine(valid, edge.double(), sil.double(), None if cover is None else cover.double())
            return LikelihoodTerms(*(None if t is None else t.cpu().numpy() for t in (
                terms.edge, terms.silhouette, terms.coverage, terms.log_likelihood)))

    def _segment_frames(self, poses):
        """Segment rotations ``p x S x 3 x 3`` and origins ``p x S x 3`` (mm) of poses ``p x D``: the compiled
        kinematics for numpy arrays, :mod:`tracker.core.torch_kinematics` for torch tensors."""
        if isinstance(poses, np.ndarray):
            from tracker.core.kinematics import forward_kinematics

            return forward_kinematics(self.model, poses).segment_rotations()
        from tracker.core.torch_kinematics import torch_kinematics

        return torch_kinematics(self.model, poses.device, poses.dtype)(poses)

    def array_costs(self, poses, maps: "_CostMaps", dtype=None):
        """Edge, silhouette and (optional) coverage costs ``p x V`` of poses ``p x D`` within the limits: the
        device path, written against the array API (torch tensors with ``maps`` on their device, or numpy
        arrays).

        Computed in ``dtype`` from the camera frames on (default float32: sub-pixel error about 1e-4 px),
        components on the leading axis and the views next, so every step runs over long contiguous arrays
        ``V x p x S (x 4 or N)``. The CPU path (:func:`likelihoods.compiled_costs.cone_costs`) runs the same
        steps in one compiled loop in float64.
        """
        maps = maps.padded() if isinstance(maps.edge, np.ndarray) else maps  # (on a device: padded when moved)
        rotations, origins = self._segment_frames(poses)  # p S 3 3, p S 3
        xp = namespace(rotations)
        axes, origins = self.rig.frames_in_cameras(rotations, origins, xp.float32 if dtype is None else dtype)
        X, Y, Z = contour_corners(self.model, axes, origins)  # each V p S 4: line 0 proximal, distal; line 1
        u, v = self.rig.pixels(X, Y, Z)
        behind = xp.any(Z <= 0, axis=-1)
        u[behind] = -1e6  # reads the border of the cost maps: cost 1
        v[behind] = -1e6
        cover = None
        if self.config.bidirectional:
            EX, EY, EZ = end_ellipse_points(self.model, axes, origins)
            eu, ev = self.rig.pixels(EX, EY, EZ)
            ends_behind = behind | xp.any(EZ <= 0, axis=-1)  # (an end cut by the camera's plane covers nothing)
            eu[ends_behind], ev[ends_behind] = -1e6, -1e6
            cover = _uncovered(u, v, eu, ev, maps.foreground)
        # Every sample is a fixed affine combination of the 4 corners: contour points spaced evenly along
        # each projected line (a ruling projects to a straight segment; with lens distortion a sub-pixel
        # approximation on a limb), then the grid between the lines. One matrix product per coordinate.
        V, p, S = Z.shape[:3]
        weights = xp.asarray(self.weights, dtype=u.dtype, device=device_of(u))
        x = xp.reshape(xp.reshape(u, (-1, 4)) @ weights, (V, p, S, -1))
        y = xp.reshape(xp.reshape(v, (-1, 4)) @ weights, (V, p, S, -1))
        nc = self.n_contour
        flat = maps.flat_index(x, y)
        edge = xp.mean(xp.reshape(maps.edge[flat[..., :nc]], (V, p, -1)), axis=-1)
        sil = xp.mean(xp.reshape(maps.silhouette[flat[..., nc:]], (V, p, -1)), axis=-1)
        return xp.permute_dims(edge, (1, 0)), xp.permute_dims(sil, (1, 0)), cover


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
    ``2 n_along`` contour points, then ``n_across x n_along`` grid points. float64; the array path casts them
    to its dtype."""
    s = np.linspace(0.0, 1.0, n_along)
    rows = [[1 - si, si, 0.0, 0.0] for si in s] + [[0.0, 0.0, 1 - si, si] for si in s]
    for t in np.arange(1, n_across + 1) / (n_across + 1):
        rows += [[(1 - t) * (1 - si), (1 - t) * si, t * (1 - si), t * si] for si in s]
    return np.array(rows).T


#: The fewest and the most particles per block on the CPU path (see ``terms``).
MIN_BLOCK = 64
MAX_BLOCK = 512
#: The most with the bidirectional term, whose blocks keep their cones' corners and end ellipses in pixels
#: (``V x p x S x 10`` float64) for the coverage loop.
BLOCK_BIDIRECTIONAL = 256
#: Particles per block on a device: about 1.5 GB of intermediates at 15 cones x 4 views, so that a GPU of 4 GB
#: holds a block.
DEVICE_BLOCK = 32768
#: The same with the bidirectional term, whose point-in-quadrilateral test holds ``p x S x 4 x F`` arrays
#: (about 150 MB each at 4096 particles, 15 cones, 150 foreground pixels).
DEVICE_BLOCK_BIDIRECTIONAL = 4096


#: Border (pixels) of cost 1 around the array path's cost maps, so that its lookups need no bounds test.
PAD = 32


class _CostMaps:
    """Per-frame cost maps ``(1 - edge)^2`` and ``(1 - silhouette)^2`` (float32, flat, the views one after the
    other: view ``k`` starts at ``view_offset[k]``, each ``height x width``), and (for the bidirectional term) a
    fixed sample of foreground pixels per view. The CPU path reads them as they are (a point off the image costs
    1); the array path reads them :meth:`padded` with ``pad`` pixels of cost 1 (numpy arrays, or torch tensors
    on a device after :meth:`to`)."""

    def __init__(self, edge, silhouette, foreground: list, view_offset, height: int, width: int, pad: int = 0):
        self.edge, self.silhouette, self.foreground = edge, silhouette, foreground
        self.view_offset, self.height, self.width, self.pad = view_offset, height, width, pad
        self._padded: _CostMaps | None = None

    @classmethod
    def of(cls, obs: Observations, n_foreground: int = 0, threads: int = 1) -> "_CostMaps":
        """The cost maps of ``obs``, the views made on ``threads`` threads in turn."""
        V, H, W = obs.edges.shape
        edge, sil = np.empty((V, H, W), np.float32), np.empty((V, H, W), np.float32)

        def view(v: int) -> None:
            for cost, m in ((edge[v], obs.edges[v]), (sil[v], obs.silhouettes[v])):
                np.square(np.subtract(1.0, m, out=cost), out=cost)

        share(view, range(V), threads)
        fg = [foreground_sample(sil, n_foreground) for sil in obs.silhouettes] if n_foreground else []
        return cls(edge.reshape(-1), sil.reshape(-1), fg, np.arange(V, dtype=np.int64) * (H * W), H, W)

    def padded(self) -> "_CostMaps":
        """The same maps (numpy) with a border of :data:`PAD` pixels of cost 1 (made once)."""
        if self.pad:
            return self
        if self._padded is not None:
            return self._padded
        V, H, W = len(self.view_offset), self.height, self.width
        Hp, Wp = H + 2 * PAD, W + 2 * PAD

        def pad(m: np.ndarray) -> np.ndarray:
            out = np.ones((V, Hp, Wp), np.float32)
            out[:, PAD:PAD + H, PAD:PAD + W] = m.reshape(V, H, W)
            return out.reshape(-1)
        self._padded = _CostMaps(pad(self.edge), pad(self.silhouette), self.foreground,
                                 np.arange(V, dtype=np.int64) * (Hp * Wp), Hp, Wp, PAD)
        return self._padded

    def to(self, device) -> "_CostMaps":
        """The :meth:`padded` maps as torch tensors on ``device``."""
        import torch

        def move(a: np.ndarray):
            return torch.as_tensor(a).to(device)
        padded = self.padded()
        return _CostMaps(move(padded.edge), move(padded.silhouette), [move(f) for f in padded.foreground],
                         move(padded.view_offset), padded.height, padded.width, padded.pad)

    def flat_index(self, x, y):
        """Flat int64 indices ``V x ...`` into the :meth:`padded` maps of the nearest pixels to the points
        ``(x, y)`` (float32 pixels of the unpadded images, views leading; clamped to the padded maps; ``x`` and
        ``y`` are used as scratch): the array path's lookup. The CPU path's,
        :func:`likelihoods.compiled_costs.cone_costs`, computes the same pixels in its loop."""
        if not self.pad:
            raise ValueError("flat_index reads padded cost maps (see _CostMaps.padded)")
        xp = namespace(x)
        x += self.pad + 0.5
        y += self.pad + 0.5
        ix = xp.astype(xp.clip(x, 0, self.width - 1), xp.int64)  # torch indexes with int64
        iy = xp.astype(xp.clip(y, 0, self.height - 1), xp.int64)
        iy *= self.width
        iy += ix
        iy += xp.reshape(self.view_offset, (-1,) + (1,) * (iy.ndim - 1))
        return iy


#: Pixels between the silhouette's outline and the foreground pixels the bidirectional term samples.
FOREGROUND_MARGIN = 2


def foreground_sample(silhouette: np.ndarray, n: int) -> np.ndarray:
    """``n`` foreground pixels ``(x, y)`` spread evenly over the silhouette's pixels at least ``FOREGROUND_MARGIN``
    pixels inside its outline (deterministic): the outline's own pixels are as often background blurred into
    the silhouette as body, and a body drawn larger than it is would be rewarded for covering them."""
    import cv2

    whole = silhouette > 0.5
    size = 2 * FOREGROUND_MARGIN + 1
    inner = cv2.erode(whole.astype(np.uint8), np.ones((size, size), np.uint8)).astype(bool)
    ys, xs = np.nonzero(inner if inner.any() else whole)  # (a silhouette thinner than the margin: all of it)
    if len(xs) == 0:
        return np.zeros((0, 2), np.float32)
    idx = np.linspace(0, len(xs) - 1, min(n, len(xs))).astype(int)
    return np.stack([xs[idx], ys[idx]], axis=1).astype(np.float32)


def _uncovered(u, v, eu, ev, foreground: list):
    """Fraction ``p x V`` of the sampled foreground pixels (``F x 2`` per view) outside every projected cone.

    A cone's projection is the quadrilateral of its contour lines' end points (pixels ``u``, ``v``
    ``V x p x S x 4``) and the images of its two end ellipses (pixels ``eu``, ``ev`` ``V x p x S x 6``, of
    :func:`tracker.core.cones.end_ellipse_points`): the contour lines touch the ends' images, so the three
    together are the truncated cone's outline. numpy arrays, or torch tensors on one device."""
    xp = namespace(u)
    V, p = u.shape[:2]
    out = xp.zeros((p, V), dtype=xp.float64, device=device_of(u))
    around = [0, 1, 3, 2]  # the quadrilateral's corners in order
    for view in range(V):  # views only; particles, segments and pixels are batched
        fg = foreground[view]
        if fg.shape[0] == 0:
            continue
        fx, fy = fg[:, 0], fg[:, 1]
        qx, qy = u[view][..., around], v[view][..., around]  # p S 4
        ex, ey = xp.roll(qx, -1, axis=2) - qx, xp.roll(qy, -1, axis=2) - qy
        cross = ex[..., None] * (fy - qy[..., None]) - ey[..., None] * (fx - qx[..., None])  # p S 4 F
        inside = xp.all(cross > 0, axis=2) | xp.all(cross < 0, axis=2)  # p S F (a cone behind the camera: none)
        for end in (0, 3):
            cx, cy = eu[view][..., end, None], ev[view][..., end, None]  # p S 1
            ax, ay = eu[view][..., end + 1, None] - cx, ev[view][..., end + 1, None] - cy
            bx, by = eu[view][..., end + 2, None] - cx, ev[view][..., end + 2, None] - cy
            det = ax * by - ay * bx
            dx, dy = fx - cx, fy - cy  # p S F
            alpha, beta = dx * by - dy * bx, ax * dy - ay * dx  # times det
            inside = inside | (alpha * alpha + beta * beta < det * det)  # (an end seen edge-on: det 0, none)
        out[:, view] = 1.0 - xp.mean(xp.astype(xp.any(inside, axis=1), xp.float64), axis=1)
    return out


@register_likelihood(
    "edge-silhouette", summary="Deutscher & Reid's edge + silhouette likelihood, summed over views",
    options=(Option("sharpness", float, EdgeSilhouetteConfig.sharpness, "likelihood sharpness", minimum=0.0,
                    strict=True, maximum=1e6),
             Option("bidirectional", bool, EdgeSilhouetteConfig.bidirectional,
                    "also penalise the foreground no projected cone covers, so that a body drawn smaller or larger "
                    "than the person scores worse (off: the one-directional silhouette cost of Deutscher & Reid)"),
             *GROUND_OPTIONS))
def build_edge_silhouette(context: LikelihoodContext, options: dict) -> Likelihood:
    config = EdgeSilhouetteConfig(sharpness=options["sharpness"], bidirectional=options["bidirectional"])
    # On the CPU the compiled path (faster there than torch); "cpu:0" too.
    device = None if is_cpu(context.device) else context.device
    images = EdgeSilhouetteLikelihood(context.body_model, context.rig, config, device=device, threads=context.threads)
    ground = ground_contact_config(len(context.rig), options["ground_std"], options["root_height_std"])
    return SumOfLikelihoods([images, GroundContact(context.body_model, ground)]) if ground.active else images
