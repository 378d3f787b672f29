"""How the particle filter weighs and resamples its particles: one small strategy object per filter.

The filter (:mod:`tracker.engine.filter`) proposes, anneals, recovers and estimates the same way for every
prior; what differs is how a frame's likelihood becomes the particles' weights and how the particles are
redrawn. :func:`weighing_for` chooses the strategy once, from the prior: plain sequential importance resampling
(:class:`PlainSIR`), or, for a prior whose particles are split into components the filter keeps apart, mixture
tracking (:class:`tracker.engine.multiple_models.MixtureTracking`). A strategy implements :class:`Weighing`.
"""
from __future__ import annotations

from typing import Callable, Protocol, runtime_checkable

import numpy as np

from tracker.engine.multiple_models import MixtureTracking, mixing_of
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.weights import LogWeights


@runtime_checkable
class Weighing(Protocol):
    """Weights from a frame's likelihood, and resampling, for ``P`` particles.

    ``start_weights(state)``: the log-weights ``(P,)`` a particle set starts with (the first frame, and after a
    lost frame) for the prior's per-particle ``state``; ``groups(state)``: the particle index sets ``(n,)`` that
    annealing layers sharpen and redraw each on its own; ``weigh(carried, log_likelihood, evidence, state)``: the
    log-weights and the normalised weights ``(P,)`` from the carried log-weights and the frame's log-likelihood
    ``(P,)`` (``evidence`` ``(P,)``: the log-likelihood of the prior's own samples, before annealing moved them),
    or None when no particle has any weight (the filter then re-diffuses the particles and weighs again);
    ``resample(weights, normalised, state, due, rng)``: the indices ``(P,)`` drawn (None: not resampled), the
    log-weights carried to the next frame, and the prior's state reindexed with the particles; ``due`` is the
    filter's rule (an annealed frame, or the effective sample size below its threshold).
    """

    def start_weights(self, state: PriorState) -> LogWeights: ...

    def groups(self, state: PriorState) -> list[np.ndarray]: ...

    def weigh(self, carried: LogWeights, log_likelihood: np.ndarray, evidence: np.ndarray,
              state: PriorState) -> tuple[LogWeights, np.ndarray] | None: ...

    def resample(self, weights: LogWeights, normalised: np.ndarray, state: PriorState, due: bool,
                 rng: np.random.Generator) -> tuple[np.ndarray | None, LogWeights, PriorState]: ...


class PlainSIR:
    """Sequential importance resampling: the carried weights times the likelihood; resampled (with ``scheme``)
    when the filter's rule says so, else the weights carried on."""

    def __init__(self, prior: MotionPrior, scheme: Callable[..., np.ndarray], n_particles: int):
        self.prior, self.scheme, self.n_particles = prior, scheme, n_particles

    def start_weights(self, state: PriorState) -> LogWeights:
        return LogWeights.uniform(self.n_particles)

    def groups(self, state: PriorState) -> list[np.ndarray]:
        return [np.arange(self.n_particles)]

    def weigh(self, carried: LogWeights, log_likelihood: np.ndarray, evidence: np.ndarray,
              state: PriorState) -> tuple[LogWeights, np.ndarray] | None:
        weights = carried.add(log_likelihood)
        return (weights, weights.normalised) if weights.any_finite else None

    def resample(self, weights: LogWeights, normalised: np.ndarray, state: PriorState, due: bool,
                 rng: np.random.Generator) -> tuple[np.ndarray | None, LogWeights, PriorState]:
        if not due:
            return None, weights.renormalised(), state
        idx = self.scheme(normalised, rng)
        return idx, LogWeights.uniform(self.n_particles), self.prior.reindex(state, idx)


def weighing_for(prior: MotionPrior, scheme: Callable[..., np.ndarray], n_particles: int) -> Weighing:
    """The strategy for ``prior``: mixture tracking where its particles are split into components kept apart
    (:func:`tracker.engine.multiple_models.mixing_of`), else plain SIR."""
    if mixing_of(prior) is not None:
        return MixtureTracking(prior, scheme, n_particles)
    return PlainSIR(prior, scheme, n_particles)
