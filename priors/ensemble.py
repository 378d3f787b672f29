"""An ensemble of priors of one kind and order: each particle is drawn by one member, for the whole run.

A learned prior's tracking error depends much on its training seed (the same CRBM trained with five
seeds gave 0.46-0.77 of zero-velocity's error on the tuning folds with 4 views, 0.83-1.92 with one;
docs/methods_report.md). Given several models, the particle set is split between them: particle ``i`` starts
with member ``i mod M`` and keeps it, so resampling shifts particles toward the members whose predictions
the images support. The members' own per-particle states are kept whole (``P`` rows each) and each member
samples and updates the rows of its particles, so resampling reindexes everything together.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from tracker.core.errors import InputError
from tracker.engine.prior import MotionPrior, PriorState, reindex_state, scatter_state


class EnsemblePrior(MotionPrior):
    """Members of one order, each drawing its share of the particles (see the module docstring).

    State: ``member`` ``(P,)``, each particle's member index, and ``member_k`` the state of member ``k`` for all
    particles. The per-frame summary (a paced CRBM's pace) is the members' summaries of their own particles
    under the whole set's weights, summed: the posterior mean over all particles, for summaries linear in the
    weights (every summary of this toolkit's priors is).
    """

    def __init__(self, members: Sequence[MotionPrior]):
        members = list(members)
        if len(members) < 2:
            raise InputError(f"an ensemble needs at least two priors, got {len(members)}")
        first = members[0]
        for m in members[1:]:
            if (m.order, m.name, m.summary_names, m.summary_kind) != \
                    (first.order, first.name, first.summary_names, first.summary_kind):
                raise InputError("an ensemble's priors must be of one kind and order, with the same per-frame summary")
        self.members = members
        self.order, self.name = first.order, first.name
        self.summary_names, self.summary_kind = first.summary_names, first.summary_kind

    def _shares(self, state: PriorState):
        """Each member with its index and the indices ``(n,)`` of its particles, for members that have any."""
        for k, m in enumerate(self.members):
            idx = np.flatnonzero(state["member"] == k)
            if len(idx):
                yield k, m, idx

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        state = {"member": np.arange(n_particles) % len(self.members)}
        for k, m in enumerate(self.members):
            state[f"member_{k}"] = m.start(known, n_particles, rng)
        return state

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        poses = np.empty((history.shape[0], history.shape[2]))
        new = dict(state)  # a member that resampling left no particles keeps its state
        for k, m, idx in self._shares(state):
            own = state[f"member_{k}"]
            poses[idx], part = m.sample(history[idx], available, reindex_state(own, idx), rng)
            new[f"member_{k}"] = scatter_state(own, idx, part)
        return poses, new

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """Each member derives the state of its own arriving particles from their histories."""
        new = dict(state)
        for k, m, idx in self._shares(state):
            own = state[f"member_{k}"]
            new[f"member_{k}"] = scatter_state(own, idx, m.adopt(reindex_state(own, idx), history[idx], available,
                                                                 rng))
        return new

    def diffusion_std(self) -> np.ndarray:
        return np.mean([m.diffusion_std() for m in self.members], axis=0)

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        parts = [m.summarize(reindex_state(state[f"member_{k}"], idx), weights[idx])
                 for k, m, idx in self._shares(state)]
        if not parts or any(p is None for p in parts):
            return None
        return np.sum(parts, axis=0)

    def settings(self) -> dict:
        return {"ensemble_of": len(self.members), "members": [m.settings() for m in self.members]}

    def label_for(self, available: int) -> str:
        return f"{self.members[0].label_for(available)} (ensemble of {len(self.members)})"
