"""The 2-D keypoint likelihood: a pose's keypoints projected into each view against a detector's keypoints.

For every particle, view and body keypoint (:data:`tracker.core.keypoints.KEYPOINTS`) the pose's keypoint is
projected and compared with the detection ``(x, y, c)`` by a robust reprojection term, an outlier mixture::

    p(detection | pose) = w * N2(detection; projection, s^2 I) + (1 - w) / (W * H),    w = c * (1 - outliers)

with ``s`` the keypoint's spread (:data:`tracker.core.keypoints.KEYPOINT_SPREAD_MM`, mm on the person, times
``spread``) seen from the camera at the keypoint's depth (``fx * mm / depth`` pixels), never below
``min_spread_px``; ``W x H`` is the image. A confident detection near the projection scores high, a wrong
one costs at most ``-log((1 - w) / (W H))``, and one of confidence 0 (not found) costs nothing at all.

A detector may label one view's left and right arms (or legs, or ears) the wrong way round. Per view and
left/right group (:data:`tracker.core.keypoints.SWAP_GROUPS`) both assignments are scored and mixed with
probability ``swap`` for the swapped one, so a swap costs little and is never mistaken for the pose.

The log-likelihood is ``weight`` times the sum over views, keypoints and groups. Poses outside the model's
joint limits get ``-inf``.

Shapes: poses ``P x D``; detections ``V x K x 3``; projections ``P x V x K x 2``; the result ``(P,)``.
Registered as ``keypoints``; ``keypoints+edge-silhouette`` adds the edge and silhouette likelihood
(:class:`tracker.engine.likelihood.SumOfLikelihoods`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError
from tracker.core.keypoints import (KEYPOINT_INDEX, KEYPOINT_SPREAD_MM, KEYPOINTS, keypoints_from_frames,
                                    swap_group_indices)
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood, RefiningFrameLikelihood, SumOfLikelihoods
from tracker.engine.registry import LIKELIHOODS, LikelihoodContext, Option, register_likelihood


@dataclass(frozen=True)
class KeypointConfig:
    """``weight`` multiplies the summed log-likelihood; ``spread`` scales every keypoint's spread (mm) of
    :data:`~tracker.core.keypoints.KEYPOINT_SPREAD_MM`; ``min_spread_px`` is the least spread in pixels;
    ``outliers`` is the share of confident detections that are wrong; ``swap`` the probability that a view's
    left/right group is swapped; ``min_confidence`` the confidence below which a detection is ignored;
    ``refine_steps`` how many steps move the filter's proposals towards the detections (0: none)."""

    weight: float = 1.0
    spread: float = 1.0
    min_spread_px: float = 1.5
    outliers: float = 0.05
    swap: float = 0.05
    min_confidence: float = 0.1
    refine_steps: int = 1

    def check(self) -> "KeypointConfig":
        if not (self.weight > 0 and self.spread > 0 and self.min_spread_px > 0):
            raise InputError(f"keypoint weight, spread and min_spread_px must be positive, got {self}")
        if not (isinstance(self.refine_steps, (int, np.integer)) and 0 <= self.refine_steps <= 10):
            raise InputError(f"keypoint refine_steps must be an integer from 0 to 10, got {self.refine_steps!r}")
        if not (0 < self.outliers < 1 and 0 <= self.swap < 1 and 0 <= self.min_confidence < 1):
            raise InputError(f"keypoint outliers must be in (0, 1), swap and min_confidence in [0, 1), got {self}")
        return self


class KeypointLikelihood(Likelihood):
    """Log-likelihood of body poses given one frame's 2-D keypoints in the cameras of ``rig`` (see the module)."""

    name = "keypoints"
    #: The refinement's Marquardt damping: the step solves ``(H + DAMPING diag(H)) step = g``.
    DAMPING = 0.5

    def __init__(self, model: BodyModel, rig: CameraRig, config: KeypointConfig = KeypointConfig()):
        self.model = model
        self.rig = rig
        self.config = config.check()
        spread = np.array([KEYPOINT_SPREAD_MM[name] for name in KEYPOINTS]) * config.spread
        self.spread_mm = spread  # (K,)
        self.focal = rig.focal.mean(axis=1)  # (V,) pixels per unit of normalised image
        self.log_uniform = -np.log(np.array([c.width * c.height for c in rig.cameras], float))  # (V,)
        grouped = self.groups = swap_group_indices()
        in_group = np.zeros(len(KEYPOINTS), bool)
        for left, right in grouped:
            in_group[left] = in_group[right] = True
        self.single = np.flatnonzero(~in_group)
        named = {"head_top": "head", **{k: k for k in KEYPOINTS if k in model.marker_names or k.endswith("_toe")}}
        names = [p.name for p in model.points]
        self.named = np.array([KEYPOINT_INDEX[k] for k in KEYPOINTS if named.get(k) in names])  # keypoints
        self.named_points = np.array([names.index(named[KEYPOINTS[k]]) for k in self.named])  # model points
        where = {int(k): i for i, k in enumerate(self.named)}  # a keypoint's place among the refined ones
        self.refine_groups = [(np.array([where[i] for i in left if i in where]),
                               np.array([where[i] for i in right if i in where]))
                              for left, right in grouped if all(i in where for i in np.r_[left, right])]

    def settings(self) -> dict:
        c = self.config
        return {"weight": c.weight, "spread": c.spread, "min_spread_px": c.min_spread_px, "outliers": c.outliers,
                "swap": c.swap, "min_confidence": c.min_confidence, "refine_steps": c.refine_steps}

    def prepare(self, frame: Frame) -> "PreparedKeypoints":
        """The frame's keypoints, checked against the views; an :class:`InputError` when it has none."""
        if frame.keypoints is None:
            raise InputError(f"frame {frame.index} has no keypoints: the keypoint likelihood needs the "
                             "sequence's keypoints (pose-tracker keypoints SEQ)")
        if frame.n_views != len(self.rig):
            raise InputError(f"frame {frame.index} has {frame.n_views} views but the rig has {len(self.rig)} cameras")
        detections = np.array(frame.keypoints, float)
        if detections.shape != (len(self.rig), len(KEYPOINTS), 3):
            raise InputError(f"frame {frame.index}'s keypoints are {detections.shape}, expected "
                             f"{(len(self.rig), len(KEYPOINTS), 3)}")
        detections[~np.isfinite(detections[..., :2]).all(axis=-1), 2] = 0.0  # no pixels: not found
        return (RefiningKeypoints if self.config.refine_steps else PreparedKeypoints)(self, detections)

    def view_terms(self, poses: np.ndarray, detections: np.ndarray) -> np.ndarray:
        """Per-view log-likelihoods ``P x V`` of poses ``P x D`` (unweighted, swaps mixed in); the keypoints'
        detections ``V x K x 3``."""
        from tracker.core.kinematics import forward_kinematics  # numba: loaded when scoring, not when registering

        c = self.config
        fk = forward_kinematics(self.model, poses)
        points = keypoints_from_frames(self.model, fk.rotations, fk.origins)  # P x K x 3
        pixels, depth = self.rig.project(points)  # P x V x K x 2, P x V x K
        conf = np.where(detections[..., 2] >= c.min_confidence, detections[..., 2], 0.0)  # V x K
        observed = np.nan_to_num(detections[..., :2])
        spread_px = np.maximum(self.focal[:, None] * self.spread_mm[None, :] / np.maximum(depth, 1.0),
                               c.min_spread_px)  # P x V x K
        log_in = np.log(np.maximum(conf * (1.0 - c.outliers), 1e-300))  # V x K
        log_out = np.log1p(-conf * (1.0 - c.outliers)) + self.log_uniform[:, None]  # V x K

        def score(points: np.ndarray, labels: np.ndarray) -> np.ndarray:
            """Log terms ``P x V x k`` of the pose's keypoints ``points`` against the detections labelled
            ``labels`` (``(k,)`` each)."""
            r2 = np.sum((pixels[:, :, points] - observed[None, :, labels]) ** 2, axis=-1)
            s = spread_px[:, :, points]
            inlier = log_in[None, :, labels] - np.log(2.0 * np.pi) - 2.0 * np.log(s) - 0.5 * r2 / s ** 2
            inlier = np.where(depth[:, :, points] > 0, inlier, -np.inf)
            mixed = np.logaddexp(inlier, log_out[None, :, labels])
            # a keypoint not found (confidence 0) adds nothing: log((1 - 0) / (W H)) is the same for every pose
            return np.where(conf[None, :, labels] > 0, mixed - log_out[None, :, labels], 0.0)

        total = score(self.single, self.single).sum(axis=-1)
        keep, swap = np.log1p(-c.swap), (np.log(c.swap) if c.swap > 0 else -np.inf)
        for left, right in self.groups:
            both = np.concatenate([left, right])
            as_labelled = score(both, both).sum(axis=-1)
            if c.swap > 0:
                crossed = score(both, np.concatenate([right, left])).sum(axis=-1)
                total = total + np.logaddexp(keep + as_labelled, swap + crossed)
            else:
                total = total + as_labelled
        return total

    def log_likelihood(self, poses: np.ndarray, detections: np.ndarray) -> np.ndarray:
        """Log-likelihoods ``(P,)`` of poses ``P x D`` (``-inf`` outside the joint limits)."""
        poses = np.asarray(poses, float)
        if poses.ndim != 2 or poses.shape[1] != self.model.n_dofs:
            raise InputError(f"poses must be P x {self.model.n_dofs}, got shape {poses.shape}")
        if len(poses) == 0:
            return np.zeros(0)
        valid = self.model.within_limits(poses) & np.isfinite(poses).all(axis=1)
        poses = np.where(valid[:, None], poses, self.model.rest_pose())
        out = self.config.weight * self.view_terms(poses, detections).sum(axis=-1)
        return np.where(valid, out, -np.inf)

    def refine(self, poses: np.ndarray, detections: np.ndarray, steps: int = 1) -> np.ndarray:
        """Poses ``P x D`` moved towards the detections ``V x K x 3``: ``steps`` Levenberg-Marquardt steps on the
        keypoints that are named points of the model (the joints, the head's top, the toes), each a
        Gauss-Newton step on the confidence-weighted reprojection error with the robust (Cauchy) weights of the
        current residuals, damped as Marquardt does (each number's own curvature times :attr:`DAMPING`, so that
        millimetres and radians alike take a part of the full step); the result clipped to the
        joint limits. Batched over particles: one ``D x D`` solve each. In each view a left/right group is read as
        labelled or swapped, whichever its points fit better (a swap costs the likelihood's log odds of one), as
        the likelihood reads it."""
        from tracker.core.kinematics import forward_kinematics, point_jacobians

        c = self.config
        conf = np.where(detections[..., 2] >= c.min_confidence, detections[..., 2], 0.0)[:, self.named]  # V x k
        observed = np.nan_to_num(detections[..., :2])[:, self.named]  # V x k x 2
        R, t = self.rig.R, self.rig.t[None, None]
        f = self.rig.focal  # V x 2
        D = self.model.n_dofs
        out = np.asarray(poses, float).copy()
        V, k = len(self.rig), len(self.named)
        rows = R.reshape(3 * V, 3)  # the cameras' rotations stacked: one product for every particle and point
        for _ in range(steps):
            P = len(out)
            fk = forward_kinematics(self.model, out)
            X = fk.points[:, self.named_points]  # P x k x 3
            J = point_jacobians(self.model, out, fk, self.named_points)  # P x k x 3 x D, laid out P x k x D x 3
            Xc = (X.reshape(-1, 3) @ rows.T).reshape(P, k, V, 3) + t  # P x k x V x 3
            z = np.maximum(Xc[..., 2], 1.0)
            JXc = (np.swapaxes(J, -1, -2).reshape(-1, 3) @ rows.T).reshape(P, k, D, V, 3).transpose(3, 4, 0, 1, 2)
            pixels, _ = self.rig.project(X)  # P x V x k x 2 (with the lens distortion)
            zv = z.transpose(2, 0, 1)  # V x P x k
            s2 = np.maximum(self.focal[:, None, None] * self.spread_mm[self.named][None, None, :] / zv,
                            c.min_spread_px) ** 2
            r, weight = self._labelled(pixels, observed, conf, s2.transpose(1, 0, 2))  # P x V x k (x 2)
            w = weight.transpose(1, 0, 2) / (s2 + np.sum(r ** 2, axis=-1).transpose(1, 0, 2))  # Cauchy weights / s^2
            root = np.sqrt(np.where(Xc[..., 2].transpose(2, 0, 1) > 0, w, 0.0)) / zv  # V x P x k
            A = np.empty((P, D, V, k, 2))
            b = np.empty((P, V, k, 2))
            for a in (0, 1):  # d(u, v) / d(pose), without the lens distortion's small derivative
                d = (JXc[:, a] - (Xc[..., a].transpose(2, 0, 1) / z.transpose(2, 0, 1))[..., None] * JXc[:, 2])
                d *= (f[:, a][:, None, None] * root)[..., None]  # V x P x k x D
                A[..., a] = d.transpose(1, 3, 0, 2)
                b[..., a] = r[..., a] * (root * zv).transpose(1, 0, 2)
            A = A.reshape(P, D, -1)
            H = A @ A.transpose(0, 2, 1)
            H[:, np.arange(D), np.arange(D)] *= 1.0 + self.DAMPING  # Marquardt: each number damped in its own units
            H[:, np.arange(D), np.arange(D)] += 1e-9
            g = (A @ b.reshape(P, -1, 1))[..., 0]
            out = self.model.clip_to_limits(out + np.linalg.solve(H, g[..., None])[..., 0])
        return out


    def _labelled(self, pixels: np.ndarray, observed: np.ndarray, conf: np.ndarray, s2: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals ``P x V x k x 2`` and confidences ``P x V x k`` of the refined keypoints (the model's projected
        ``pixels`` ``P x V x k x 2`` against ``observed`` ``V x k x 2`` of confidence ``conf`` ``V x k``; squared
        spreads ``s2`` ``P x V x k``), each view's left/right groups read as labelled or swapped, whichever costs
        less (a swap costing the likelihood's log odds of one)."""
        r = observed[None] - pixels
        weight = np.broadcast_to(conf[None], r.shape[:-1]).copy()
        penalty = np.log((1.0 - self.config.swap) / self.config.swap) if self.config.swap > 0 else np.inf
        for left, right in self.refine_groups:
            both, crossed = np.r_[left, right], np.r_[right, left]
            swapped_r = observed[None][:, :, crossed] - pixels[:, :, both]
            cost_as_labelled = (conf[None, :, both] * np.log1p(np.sum(r[:, :, both] ** 2, -1) / s2[:, :, both])).sum(-1)
            cost_swapped = (conf[None, :, crossed] * np.log1p(np.sum(swapped_r ** 2, -1) / s2[:, :, both])).sum(-1)
            swap = (cost_swapped + penalty < cost_as_labelled)[..., None]  # P x V x 1
            r[:, :, both] = np.where(swap[..., None], swapped_r, r[:, :, both])
            weight[:, :, both] = np.where(swap, conf[None, :, crossed], weight[:, :, both])
        return r, weight


class PreparedKeypoints(FrameLikelihood):
    """The keypoint likelihood bound to one frame's detections ``V x K x 3``."""

    def __init__(self, likelihood: KeypointLikelihood, detections: np.ndarray):
        self.likelihood = likelihood
        self.detections = detections

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        return self.likelihood.log_likelihood(poses, self.detections)


class RefiningKeypoints(PreparedKeypoints, RefiningFrameLikelihood):
    """The keypoint likelihood of one frame that also moves the filter's proposals towards the detections
    (``refine_steps`` steps of :meth:`KeypointLikelihood.refine`)."""

    def refine(self, poses: np.ndarray) -> np.ndarray:
        return self.likelihood.refine(poses, self.detections, self.likelihood.config.refine_steps)


_OPTIONS = (
    Option("keypoint_weight", float, KeypointConfig.weight, "multiplies the keypoint log-likelihood",
           minimum=0.0, strict=True, maximum=1e6),
    Option("keypoint_spread", float, KeypointConfig.spread,
           "scales each keypoint's spread on the person (mm; 30-50 mm at 1)", minimum=0.0, strict=True,
           maximum=100.0),
    Option("keypoint_outliers", float, KeypointConfig.outliers, "share of confident detections that are wrong",
           minimum=0.0, strict=True, maximum=1.0, strict_max=True),
    Option("keypoint_swap", float, KeypointConfig.swap,
           "probability that a view's left and right arms, legs or ears are swapped", minimum=0.0, maximum=1.0,
           strict_max=True),
    Option("keypoint_refine", int, KeypointConfig.refine_steps,
           "steps that move each proposed pose towards the keypoints before it is weighed (0: none)",
           minimum=0, maximum=10),
)


def _config(options: dict) -> KeypointConfig:
    return KeypointConfig(weight=options["keypoint_weight"], spread=options["keypoint_spread"],
                          outliers=options["keypoint_outliers"], swap=options["keypoint_swap"],
                          refine_steps=options["keypoint_refine"])


@register_likelihood("keypoints", summary="2-D keypoints of a detector, robust to outliers and left/right swaps",
                     options=_OPTIONS)
def build_keypoints(context: LikelihoodContext, options: dict) -> KeypointLikelihood:
    return KeypointLikelihood(context.body_model, context.rig, _config(options))


def _edge_silhouette_options() -> tuple[Option, ...]:
    import likelihoods.edge_silhouette  # noqa: F401 -- registers edge-silhouette

    return LIKELIHOODS.get("edge-silhouette").options


@register_likelihood("keypoints+edge-silhouette",
                     summary="keypoints and Deutscher & Reid's edge + silhouette likelihood together",
                     options=_OPTIONS + _edge_silhouette_options())
def build_keypoints_and_silhouettes(context: LikelihoodContext, options: dict) -> SumOfLikelihoods:
    silhouettes = LIKELIHOODS.get("edge-silhouette")
    own = {o.name: options[o.name] for o in silhouettes.options}
    return SumOfLikelihoods([build_keypoints(context, options), silhouettes.build(context, own)])
