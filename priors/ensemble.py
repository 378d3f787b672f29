"""Particles split among motion models: the one way this toolkit composes priors, and the ensemble.

:class:`Composite` is the mechanism: every particle is drawn by one of several motion models (its component),
and each model keeps its own per-particle state whole (``P`` rows) and samples and updates the rows of its own
particles, so resampling reindexes everything together. Two priors use it:

- the **ensemble** (:class:`EnsemblePrior`, below): models of one kind and order (the same prior trained with
  several seeds); a particle's component travels with it when resampling copies it, so resampling shifts
  particles toward the members whose predictions the images support, and the filter weighs them as plain SIR;
- the **mixture of priors** (:class:`priors.mixture.MixturePrior`): different motion models, each holding a
  fixed share of the particle positions, which the filter keeps apart and weighs by their evidence (mixture
  tracking, :mod:`tracker.engine.multiple_models`); a model whose particles carry components of their own (an FCRBM's
  style labels, :class:`~tracker.engine.multiple_models.ComponentPrior`) takes part with each of them.

A learned prior's tracking error depends much on its training seed (the same CRBM trained with five
seeds gave 0.46-0.77 of zero-velocity's error on the tuning folds with 4 views, 0.83-1.92 with one;
docs/methods_report.md): the ensemble splits the particle set between several such models, particle ``i``
starting with member ``i mod M``.

State: ``component`` ``(P,)``, each particle's model; ``arrived`` ``(P,)``, the particles that came from another
model at a resampling and have not been drawn since (the new model derives its pose-dependent state from their
own histories first, :func:`tracker.engine.prior.adopt`); ``model_k``, model ``k``'s state for all particles,
of which the rows of its own particles are in use.
"""
from __future__ import annotations

from abc import abstractmethod
from typing import Iterator, Sequence

import numpy as np

from tracker.core.errors import InputError
from tracker.engine.prior import (MotionPrior, PriorState, adopt, label_for, reindex_state, scatter_state,
                                  summarize, summary_of)


class Composite(MotionPrior):
    """Motion models each drawing the particles of its component (module docstring).

    A subclass says how the particles are first laid out among the models (:meth:`layout`) and what resampling
    does to a particle's component (:meth:`reindex`), and reports (scale, summary, label, settings) as fits it.
    """

    def __init__(self, components: Sequence[MotionPrior]):
        self.components = list(components)
        self.order = max(m.order for m in self.components)

    @abstractmethod
    def layout(self, n_particles: int) -> np.ndarray:
        """Each particle's model ``(P,)`` at the start."""

    def shares(self, component: np.ndarray) -> Iterator[tuple[int, MotionPrior, np.ndarray]]:
        """Each model with its index and the indices ``(n,)`` of its particles, for models that have any."""
        for k, model in enumerate(self.components):
            idx = np.flatnonzero(component == k)
            if len(idx):
                yield k, model, idx

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        state: dict = {"component": self.layout(n_particles), "arrived": np.zeros(n_particles, bool)}
        for k, model in enumerate(self.components):
            state[f"model_{k}"] = model.start(known, n_particles, rng)
        return state

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        """Every model draws its own particles from their histories (the last of them its order needs), having
        first derived the state of the particles that arrived from another model (:func:`adopt`)."""
        component, arrived = state["component"], state["arrived"]
        poses = np.empty((history.shape[0], history.shape[2]))
        new = {**state, "arrived": np.zeros(len(component), bool)}  # a model without particles keeps its state
        for k, model, m in self.shares(component):
            own = reindex_state(state[f"model_{k}"], m)
            moved = np.flatnonzero(arrived[m])
            if len(moved):
                own = scatter_state(own, moved, adopt(model, reindex_state(own, moved), history[m[moved]],
                                                      available, rng))
            h = history[m, history.shape[1] - model.order:]
            poses[m], drawn = model.sample(h, min(available, model.order), own, rng)
            new[f"model_{k}"] = scatter_state(state[f"model_{k}"], m, drawn)
        return poses, new

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """As a component of a mixture: each model derives the state of its own arriving particles from their
        histories ``P x N x D``."""
        new = dict(state)
        for k, model, idx in self.shares(state["component"]):
            own = state[f"model_{k}"]
            part = adopt(model, reindex_state(own, idx), history[idx], available, rng)
            new[f"model_{k}"] = scatter_state(own, idx, part)
        return new


class EnsemblePrior(Composite):
    """Members of one kind and order, each drawing its share of the particles (see the module docstring).

    A particle keeps its member through resampling. The per-frame summary (a paced CRBM's pace) is the members'
    summaries of their own particles under the whole set's weights, summed: the posterior mean over all
    particles, for summaries linear in the weights (every summary of this toolkit's priors is).
    """

    def __init__(self, members: Sequence[MotionPrior]):
        members = list(members)
        if len(members) < 2:
            raise InputError(f"an ensemble needs at least two priors, got {len(members)}")
        first = members[0]
        for m in members[1:]:
            if (m.order, m.name, summary_of(m)) != (first.order, first.name, summary_of(first)):
                raise InputError("an ensemble's priors must be of one kind and order, with the same per-frame summary")
        super().__init__(members)
        self.name = first.name
        self.summary_names, self.summary_kind = summary_of(first)

    def layout(self, n_particles: int) -> np.ndarray:
        """Interleaved: particle ``i`` starts with member ``i mod M``."""
        return np.arange(n_particles) % len(self.components)

    def reindex(self, state: PriorState, idx: np.ndarray) -> PriorState:
        """Every particle copied with its member and its member's rows."""
        new: dict = {"component": state["component"][idx], "arrived": state["arrived"][idx]}
        for k, model in enumerate(self.components):
            new[f"model_{k}"] = model.reindex(state[f"model_{k}"], idx)
        return new

    def diffusion_std(self) -> np.ndarray:
        """The members' mean one-step scale ``(D,)``."""
        return np.mean([m.diffusion_std() for m in self.components], axis=0)

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        parts = [summarize(m, reindex_state(state[f"model_{k}"], idx), weights[idx])
                 for k, m, idx in self.shares(state["component"])]
        if not parts or any(p is None for p in parts):
            return None
        return np.sum(parts, axis=0)

    def settings(self) -> dict:
        return {"ensemble_of": len(self.components), "members": [m.settings() for m in self.components]}

    def label_for(self, available: int) -> str:
        return f"{label_for(self.components[0], available)} (ensemble of {len(self.components)})"
