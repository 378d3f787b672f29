"""Multiple-model filtering (mixture tracking): a particle set split into components that resampling never
merges.

(This module is the filter's mechanism; the prior that mixes registered motion models is :mod:`priors.mixture`.)

A prior whose particles carry a discrete hypothesis (the FCRBM's style label, the motion model of a mixture of
priors) can ask the filter to keep a fixed share of particles on every hypothesis (Vermaak, Doucet & Perez 2003,
"Maintaining multi-modality through mixture tracking"), with switches between hypotheses as in the interacting
multiple model filter (Blom & Bar-Shalom 1988). Without it, one frame on which a particle of the wrong hypothesis
happens to fit the images best takes nearly all the weight, resampling copies it everywhere, and the right
hypothesis is gone (measured on an activity switch: ``docs/methods_report.md``).

Such a prior implements :class:`ComponentPrior`: its :class:`Mixing` (the components' names, the switching
matrix, the evidence temperature), each particle's component, and how it relabels its particles after the
mixing step drew them across components. The filter then weighs and resamples with :class:`MixtureTracking`
instead of plain SIR (:mod:`tracker.engine.weighing` chooses, once per filter).

The posterior is ``sum_c pi_c p_c(x)``: component weights ``pi`` ``(C,)`` and, within component ``c``, the
particles at the positions where ``component == c`` with weights normalised within it. Each frame:

1. the particles are weighted by the likelihood within their component; the component weights by the
   component's mean likelihood (its evidence, the sum of its carried weights times the likelihood), the
   likelihood raised to ``1 / temperature`` for this evidence only: the likelihood's sharpness is set for
   telling poses apart, and untempered a single lucky particle decides the hypothesis;
2. the estimate and the prior's summary use the overall weights ``pi_c * w_i`` (so the components' posterior
   is the tempered one);
3. each component is redrawn from all particles, particle ``i`` weighted by ``transition[c_i, c] * W_i``
   (the IMM mixing step: a component whose weight is small restarts from the others' particles, so it can take
   over when the person changes activity), and every particle of component ``c`` carries the weight
   ``sum_i transition[c_i, c] W_i / n_c``: the predicted component weight shared equally.

Arrays: ``component`` ``(P,)`` integers in ``0..C-1``, fixed per particle position; ``transition`` ``C x C``
(row: from, column: to; rows sum to 1). Every mixture frame resamples (the filter's ESS threshold does not
apply). With no switching (a zero off the diagonal) a component that lost all its weight stays lost.

With annealing layers (:mod:`tracker.engine.filter`) each component is annealed on its own
(:meth:`MixtureTracking.groups`), so it keeps its particles; the weights within a component are its last
layer's, and the components' evidence is the likelihood of the prior's own samples, before annealing moved them
(annealing sharpens the pose within a hypothesis, and would otherwise flatter every hypothesis alike).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol, runtime_checkable

import numpy as np

from tracker.core.errors import InputError
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.weights import LogWeights


@dataclass(frozen=True)
class Mixing:
    """How a prior's components mix, fixed for a run: their ``names`` ``(C,)`` (reported, e.g. in a mixture of
    priors' posterior), the ``transition`` ``C x C`` per frame (row: from, column: to) and the ``temperature``
    (>= 1) the likelihood is raised to ``1 / temperature`` by in the components' weights."""

    names: tuple[str, ...]
    transition: np.ndarray
    temperature: float = 1.0

    def at(self, component: np.ndarray) -> "Mixture":
        """The particle set's :class:`Mixture` for the components ``component`` ``(P,)`` of its particles."""
        return Mixture(np.asarray(component), self.transition, self.temperature)


@runtime_checkable
class ComponentPrior(Protocol):
    """The optional capability of a prior whose particles are split into components the filter keeps apart.

    ``mixing()``: the components' :class:`Mixing`, or None when this prior's particles need none kept apart (an
    FCRBM told the style); ``component_of(state)``: each particle's component ``(P,)`` in the per-particle
    ``state``; ``relabel(state, component)``: the ``state`` after the mixing step drew particles across components,
    the particle at position ``i`` now belonging to ``component[i]``.
    """

    def mixing(self) -> Mixing | None: ...

    def component_of(self, state: PriorState) -> np.ndarray: ...

    def relabel(self, state: PriorState, component: np.ndarray) -> PriorState: ...


def mixing_of(prior: MotionPrior) -> Mixing | None:
    """The :class:`Mixing` of a prior with components kept apart, or None (a prior without the capability, or
    one whose particles need none kept apart)."""
    return prior.mixing() if isinstance(prior, ComponentPrior) else None


@dataclass(frozen=True)
class Mixture:
    """The components of a particle set, one frame: ``component`` ``(P,)``, ``transition`` ``C x C`` per frame, and the
    ``temperature`` (>= 1) the likelihood is raised to ``1 / temperature`` by in the component weights."""

    component: np.ndarray
    transition: np.ndarray
    temperature: float = 1.0

    def check(self, n_particles: int) -> "Mixture":
        """The mixture itself, checked as any component prior gives it: one component per particle, each with a
        particle, a transition whose rows are probabilities, a temperature of at least 1. These are checks of
        the matrix a prior built, not bounds on a user's setting: a prior checks its settings through its
        declared options (e.g. the mixture of priors' switching probability) before building it."""
        c, T = np.asarray(self.component), np.asarray(self.transition, float)
        C = T.shape[0] if T.ndim == 2 else 0
        if c.shape != (n_particles,) or C == 0 or T.shape != (C, C) or c.min() < 0 or c.max() >= C:
            raise InputError(f"mixture: need one component in 0..C-1 per particle and a C x C transition, got "
                             f"components {c.shape}, transition {T.shape}")
        if np.any(np.bincount(c, minlength=C) == 0):
            raise InputError("mixture: every component needs at least one particle")
        if np.any(T < 0) or not np.allclose(T.sum(axis=1), 1.0):
            raise InputError("mixture: the transition's rows must be probabilities summing to 1")
        if not self.temperature >= 1.0:
            raise InputError(f"mixture: the evidence temperature must be at least 1, got {self.temperature}")
        return self

    @property
    def n_components(self) -> int:
        return self.transition.shape[0]

    def start_weights(self) -> LogWeights:
        """Log-weights ``(P,)`` that give every component the same weight, shared equally by its particles."""
        counts = np.bincount(self.component, minlength=self.n_components)
        return LogWeights(-np.log(self.n_components * counts[self.component].astype(float)))


def switching(n_components: int, switch: float) -> np.ndarray:
    """The transition ``C x C`` that stays with probability ``1 - switch`` and otherwise moves to one of the
    other components, chosen uniformly."""
    if n_components == 1:
        return np.ones((1, 1))
    T = np.full((n_components, n_components), switch / (n_components - 1))
    np.fill_diagonal(T, 1.0 - switch)
    return T


def _log_sum(a: np.ndarray) -> float:
    top = np.max(a)
    return float(top + np.log(np.sum(np.exp(a - top)))) if np.isfinite(top) else -np.inf


def mixture_weights(carried: LogWeights, log_likelihood: np.ndarray, mix: Mixture,
                    evidence: np.ndarray | None = None) -> np.ndarray:
    """The overall normalised weights ``(P,)``: within each component the carried weights times the likelihood,
    normalised; times the component's posterior weight (its carried total times its tempered evidence, from
    ``evidence`` ``(P,)`` if given: the log-likelihood of the prior's own samples when annealing layers have
    moved the particles since). All zero if no particle has a finite weight, or no component any evidence."""
    log_w = carried.log_w
    ll = LogWeights(log_likelihood).log_w  # a broken (NaN) likelihood value is a particle with no weight
    ev = ll if evidence is None else LogWeights(evidence).log_w
    out = np.zeros(len(log_w))
    log_pi = np.full(mix.n_components, -np.inf)
    for c in range(mix.n_components):
        m = np.flatnonzero(mix.component == c)
        if m.size == 0:
            continue
        within = log_w[m] + ll[m]
        total = _log_sum(within)
        if not np.isfinite(total):
            continue
        out[m] = np.exp(within - total)
        log_pi[c] = _log_sum(log_w[m] + ev[m] / mix.temperature)
    if not np.any(np.isfinite(log_pi)):
        return np.zeros(len(log_w))
    pi = np.exp(log_pi - np.max(log_pi))
    return out * (pi / pi.sum())[mix.component]


def resample_components(weights: np.ndarray, mix: Mixture, rng: np.random.Generator,
                        scheme: Callable[..., np.ndarray]) -> tuple[np.ndarray, LogWeights]:
    """Indices ``(P,)`` for every particle position, and the carried log-weights: each component's positions
    redrawn (with ``scheme``) from all particles weighted by ``transition[c_i, c] * weights_i``, each carrying
    that total over the component's particle count."""
    P = len(weights)
    idx = np.empty(P, np.int64)
    carried = np.empty(P)
    for c in range(mix.n_components):
        m = np.flatnonzero(mix.component == c)
        w = mix.transition[mix.component, c] * weights
        total = float(w.sum())
        if not total > 0:  # nothing to draw from (cannot happen while any weight is positive): keep the component
            idx[m], carried[m] = m, -np.inf
            continue
        idx[m] = scheme(w / total, rng, len(m))
        carried[m] = np.log(total / len(m))
    return idx, LogWeights(carried)


class MixtureTracking:
    """Weighing and resampling with the components of ``prior`` (a :class:`ComponentPrior` whose :meth:`mixing`
    is not None) kept apart: the :class:`~tracker.engine.weighing.Weighing` strategy of mixture tracking (module
    docstring). ``scheme`` draws the indices (:data:`~tracker.engine.resampling.SCHEMES`); ``n_particles`` ``P``."""

    def __init__(self, prior: MotionPrior, scheme: Callable[..., np.ndarray], n_particles: int):
        mixing = mixing_of(prior)
        if mixing is None:
            raise ValueError(f"prior {prior.name!r} keeps no components apart")
        self.prior, self.mixing, self.scheme, self.n_particles = prior, mixing, scheme, n_particles

    def mixture(self, state: PriorState, checked: bool = True) -> Mixture:
        """The particle set's components for the per-particle ``state``, checked unless ``checked`` is False (for
        a state already checked where it was weighed)."""
        mix = self.mixing.at(self.prior.component_of(state))
        return mix.check(self.n_particles) if checked else mix

    def start_weights(self, state: PriorState) -> LogWeights:
        """Every component the same weight, shared equally by its particles."""
        return self.mixture(state).start_weights()

    def groups(self, state: PriorState) -> list[np.ndarray]:
        """The particles of each component: annealing layers sharpen and redraw each on its own."""
        component = self.mixture(state, checked=False).component
        return [np.flatnonzero(component == c) for c in range(self.mixing.transition.shape[0])]

    def weigh(self, carried: LogWeights, log_likelihood: np.ndarray, evidence: np.ndarray,
              state: PriorState) -> tuple[LogWeights, np.ndarray] | None:
        """The log-weights and normalised weights ``(P,)``: within components the carried weights times the
        likelihood, times the components' weights from their ``evidence`` (:func:`mixture_weights`); None when
        no particle has any weight, or no component's weighted particles any evidence (the filter recovers)."""
        if not carried.add(log_likelihood).any_finite:
            return None
        W = mixture_weights(carried, log_likelihood, self.mixture(state), evidence)
        if not W.sum() > 0:
            return None
        return LogWeights(np.log(W, out=np.full(len(W), -np.inf), where=W > 0)), W

    def resample(self, weights: LogWeights, normalised: np.ndarray, state: PriorState, due: bool,
                 rng: np.random.Generator) -> tuple[np.ndarray | None, LogWeights, PriorState]:
        """Every frame (``due`` does not matter): each component redrawn from all particles (the IMM mixing step,
        :func:`resample_components`), the prior's state reindexed and relabelled; the indices ``(P,)``, the
        carried log-weights and the state."""
        mix = self.mixture(state, checked=False)  # the state weighed
        idx, carried = resample_components(normalised, mix, rng, self.scheme)
        return idx, carried, self.prior.relabel(self.prior.reindex(state, idx), mix.component)
