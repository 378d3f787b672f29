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
    (``H x W x 3`` uint8) where the source has them, else ``None``. ``index`` is
    the frame's number in its sequence.
    """

    index: int
    images: tuple[np.ndarray, ...]
    masks: tuple[np.ndarray, ...] | None = None
    backgrounds: tuple[np.ndarray, ...] | None = None

    @property
    def n_views(self) -> int:
        return len(self.images)


class FrameLikelihood(ABC):
    """A likelihood bound to one frame's prepared observations."""

    @abstractmethod
    def __call__(self, poses: np.ndarray) -> np.ndarray:
        """Log-likelihoods ``(P,)`` of poses ``P x D`` (``-inf`` where a pose is impossible)."""


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
