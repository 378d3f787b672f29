"""The motion-prior interface the particle filter relies on (docs/architecture.md).

A prior of order ``N`` samples the next pose of every particle from that
particle's own last ``N`` poses (the augmented state of Isard & Blake), plus
any per-particle state of its own (e.g. GPDM latent coordinates). Shapes:
histories ``P x N x D`` (oldest first), poses ``P x D``; per-particle state is
``None``, an array with ``P`` on its leading axis, or a dict of such arrays.

Every random draw comes from the ``numpy.random.Generator`` the filter passes
in; a prior that samples with torch derives its ``torch.Generator`` from it,
so one seed fixes a whole run.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from tracker.engine.mixture import Mixture

#: A prior's own per-particle state: ``None``, an array with particles on the leading axis, or a dict of them.
PriorState = Any


def reindex_state(state: PriorState, idx: np.ndarray) -> PriorState:
    """Per-particle state after resampling: rows ``idx`` of every array (``None`` stays ``None``)."""
    if state is None:
        return None
    if isinstance(state, dict):
        return {k: reindex_state(v, idx) for k, v in state.items()}
    return state[idx]


def scatter_state(full: PriorState, rows: np.ndarray, part: PriorState) -> PriorState:
    """Per-particle state ``full`` with rows ``rows`` replaced by ``part`` (the state of those particles alone,
    e.g. after a member of a composite prior sampled them); ``None`` stays ``None``."""
    if full is None or part is None:
        if full is not None or part is not None:
            raise ValueError("a prior's state has rows for some of its particles and none for the others")
        return None
    if isinstance(full, dict):
        return {k: scatter_state(full[k], rows, part[k]) for k in full}
    out = np.array(full, copy=True)
    out[rows] = part
    return out


class MotionPrior(ABC):
    """Samples ``p(x_t | x_{t-N} .. x_{t-1})`` for a batch of particles.

    A new prior implements :meth:`sample` and :meth:`diffusion_std`, sets
    :attr:`order` and :attr:`name`, and registers a builder with
    :func:`tracker.engine.registry.register_prior` so that the API and the
    command line find it by name (see docs/extending.md).
    """

    #: How many past poses the prior conditions on.
    order: int = 1
    #: Name used on the command line and in results.
    name: str = "prior"
    #: Names of the entries of :meth:`summarize`'s vector (none: the prior has no per-frame summary).
    summary_names: tuple[str, ...] = ()
    #: What the summary is: ``"posterior"`` (probabilities of the names, summing to 1) or ``"quantity"`` (posterior
    #: means of the named quantities, e.g. a pace in mm/frame).
    summary_kind: str = "posterior"

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        """Per-particle state from the known initial poses ``n0 x D`` (none by default)."""
        return None

    @abstractmethod
    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        """Next poses ``P x D`` from histories ``P x N x D``, and the next per-particle state.

        ``available`` (1..N) says how many of the most recent history entries
        are real poses; older slots repeat the earliest known pose. A prior
        that needs more history than is available must fall back to a lower
        order (Taylor 2009, Sec. 6.4: "growing" the history).
        """

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState:
        """Per-particle state after the filter lost the person and re-diffused around its last estimates
        ``recent`` ``N x D``; ``state`` is the state the lost frame started from. By default :meth:`start` from
        ``recent``; a prior whose state counts frames (e.g. a schedule of style labels) carries the count on."""
        return self.start(recent, n_particles, rng)

    def reindex(self, state: PriorState, idx: np.ndarray) -> PriorState:
        """Per-particle state after resampling picked particles ``idx``."""
        return reindex_state(state, idx)

    def mixture(self, state: PriorState) -> "Mixture | None":
        """The components the filter must keep apart (mixture tracking, :mod:`tracker.engine.mixture`) for the
        per-particle ``state``, or None (the default): plain SIR."""
        return None

    def relabel(self, state: PriorState, component: np.ndarray) -> PriorState:
        """The per-particle ``state`` after mixture resampling drew particles across components: the particle at
        position ``i`` now belongs to ``component[i]`` (``(P,)``). Only priors with a :meth:`mixture` need it."""
        return state

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """This prior's state for particles that arrive from another motion model of a mixture
        (:mod:`priors.mixture`): ``history`` ``P x N x D`` their last poses (``N`` at least this prior's order,
        ``available`` of them real), ``state`` the rows this prior held at the positions they take. By default
        ``state`` unchanged, which is right for a prior whose state does not describe the newest pose (none, or
        a slow quantity such as a pace or a height offset); a prior that carries something derived from the
        particle's own poses (the step out of its newest pose, latent coordinates) derives it from ``history``."""
        return state

    @abstractmethod
    def diffusion_std(self) -> np.ndarray:
        """Per-dof standard deviation ``(D,)`` (pose units per frame) of the prior's one-step noise: the scale
        annealed filter layers diffuse particles with."""

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        """A per-frame summary ``(len(summary_names),)`` of the per-particle ``state`` under the normalised
        ``weights`` ``(P,)`` (e.g. the posterior over a style label the particles carry), recorded per frame as
        ``prior_summary``; None (the default) for a prior without one."""
        return None

    def settings(self) -> dict:
        """The prior's settings as plain JSON values, recorded in ``result.json`` (none by default)."""
        return {}

    def label_for(self, available: int) -> str:
        """Which model draws the next poses when ``available`` history slots are real (a prior that grows its
        history through lower orders names the one in use); recorded per frame."""
        return self.name
