"""The likelihood interface the particle filter relies on (docs/architecture.md).

A likelihood turns one frame's raw observations (:class:`Frame`: an image per
view, with foreground masks or background plates where the source has them)
into a :class:`FrameLikelihood` once, in :meth:`Likelihood.prepare`; that
object then maps any number of pose batches ``P x D`` to log-likelihoods
``(P,)`` (``-inf`` for impossible poses). Preparing once per frame keeps
per-frame work (silhouettes, edge maps, cost maps) out of the per-particle
path, and binding it to the returned object means there is no cache to go stale.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Frame:
    """One frame's observations in the views being tracked.

    ``images``: one uint8 image per view (``H x W x 3`` RGB or ``H x W`` grey); ``masks``: one
    ``H x W`` foreground mask per view (values in [0, 1]) where the source
    provides them, else ``None``; ``backgrounds``: one background plate per view
    (``H x W x 3`` uint8) where the source has them, else ``None``; ``keypoints``: 2-D keypoints
    ``V x K x 3`` (pixel x, y and a confidence in [0, 1] of the body keypoints
    :data:`tracker.core.keypoints.KEYPOINTS`; confidence 0 and NaN pixels where not found) where the
    sequence has them, else ``None``. ``index`` is the frame's number in its sequence.
    """

    index: int
    images: tuple[np.ndarray, ...]
    masks: tuple[np.ndarray, ...] | None = None
    backgrounds: tuple[np.ndarray, ...] | None = None
    keypoints: np.ndarray | None = None

    @property
    def n_views(self) -> int:
        return len(self.images)


class FrameLikelihood(ABC):
    """A likelihood bound to one frame's prepared observations."""

    @abstractmethod
    def __call__(self, poses: np.ndarray) -> np.ndarray:
        """Log-likelihoods ``(P,)`` of poses ``P x D`` (``-inf`` where a pose is impossible)."""


class RefiningFrameLikelihood(FrameLikelihood):
    """A prepared likelihood that can also move poses towards its evidence: the filter refines the prior's
    samples with :meth:`refine` before weighing them (Bray, Koller-Meier & Van Gool's *smart particle filter*,
    2007: a few steps of local optimisation per particle, so that in a space of 40 pose numbers the particles
    land where the evidence is rather than where a random step happens to put them). What it does is the
    likelihood's own setting, recorded with its options.

    The refined poses are weighed by the likelihood as if the prior had proposed them, with no correction for
    the move (as Bray et al. do): the estimate leans further towards the evidence than an exact posterior would,
    and a prior's own per-particle state (the GPDM's latent coordinates) is kept as the prior left it."""

    @abstractmethod
    def refine(self, poses: np.ndarray) -> np.ndarray:
        """Poses ``P x D`` moved towards this frame's evidence (within the body model's limits)."""


class Likelihood(ABC):
    """Scores body poses against image observations from a fixed set of calibrated views.

    A new likelihood implements :meth:`prepare` and registers a builder with
    :func:`tracker.engine.registry.register_likelihood` (see docs/extending.md).
    """

    #: Name used on the command line and in results.
    name: str = "likelihood"

    @abstractmethod
    def prepare(self, frame: Frame) -> FrameLikelihood:
        """Derive this frame's observations once; the result scores pose batches.

        The filter may call it from background threads, for several frames at once (it prepares frames
        ahead): anything it keeps between frames must be safe to share.
        """

    def settings(self) -> dict:
        """The likelihood's settings as plain JSON values, recorded in ``result.json`` (none by default)."""
        return {}

    def start(self, known: np.ndarray) -> None:
        """Sees the known poses ``n0 x D`` the filter starts from, before the first frame and again when a stopped
        run continues: a likelihood that scores against them (the floor's height) keeps what it needs. Nothing by
        default."""


class SumOfLikelihoods(Likelihood):
    """Independent evidence multiplied: the log-likelihoods of ``parts`` (each scoring the same views) added,
    each times its ``weights`` entry (1 by default). Poses impossible to any part are impossible."""

    def __init__(self, parts: "list[Likelihood]", weights: "list[float] | None" = None):
        if not parts:
            raise ValueError("a sum of likelihoods needs at least one part")
        self.parts = list(parts)
        self.weights = [1.0] * len(parts) if weights is None else [float(w) for w in weights]
        self.name = "+".join(p.name for p in self.parts)

    def prepare(self, frame: Frame) -> FrameLikelihood:
        parts = [p.prepare(frame) for p in self.parts]
        refining = [p for p in parts if isinstance(p, RefiningFrameLikelihood)]
        return (_RefiningSum if refining else _PreparedSum)(parts, self.weights)

    def settings(self) -> dict:
        return {p.name: p.settings() for p in self.parts}

    def start(self, known: np.ndarray) -> None:
        for part in self.parts:
            part.start(known)


class _PreparedSum(FrameLikelihood):
    def __init__(self, parts: "list[FrameLikelihood]", weights: "list[float]"):
        self.parts, self.weights = parts, weights

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        total = None
        for part, weight in zip(self.parts, self.weights):
            score = part(poses)
            score = score if weight == 1.0 else weight * score
            total = score if total is None else total + score
        return total


class _RefiningSum(_PreparedSum, RefiningFrameLikelihood):
    """A sum one of whose parts refines: the parts that refine do, in order."""

    def refine(self, poses: np.ndarray) -> np.ndarray:
        for part in self.parts:
            if isinstance(part, RefiningFrameLikelihood):
                poses = part.refine(poses)
        return poses
