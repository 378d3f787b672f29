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
from typing import Any, Protocol, runtime_checkable

import numpy as np

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
    """Samples ``p(x_t | x_{t-N} .. x_{t-1})`` for a batch of particles: the core every prior implements.

    A new prior implements :meth:`sample` and :meth:`diffusion_std`, sets :attr:`order` and :attr:`name`, and
    registers a builder with :func:`tracker.engine.registry.register_prior` so that the API and the command line
    find it by name (see docs/guide/extending.md). What else a prior can do is optional, each a small protocol it
    implements by defining the methods: a per-frame summary (:class:`Summarizing`), a label per frame
    (:class:`Labelling`), a restart after a lost frame (:class:`Restarting`), taking particles that come from
    another motion model (:class:`Adopting`), and particles split into components the filter keeps apart
    (:class:`tracker.engine.multiple_models.ComponentPrior`). The module functions :func:`summary_of`, :func:`summarize`,
    :func:`label_for`, :func:`restart` and :func:`adopt` call a prior's own method, or give the default for a
    prior without one.
    """

    #: How many past poses the prior conditions on.
    order: int = 1
    #: Name used on the command line and in results.
    name: str = "prior"

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

    def reindex(self, state: PriorState, idx: np.ndarray) -> PriorState:
        """Per-particle state after resampling picked particles ``idx``."""
        return reindex_state(state, idx)

    @abstractmethod
    def diffusion_std(self) -> np.ndarray:
        """Per-dof standard deviation ``(D,)`` (pose units per frame) of the prior's one-step noise: the scale
        annealed filter layers diffuse particles with."""

    def settings(self) -> dict:
        """The prior's settings as plain JSON values, recorded in ``result.json`` (none by default)."""
        return {}


# ---------------------------------------------------------------------------------------------------------------
# Optional capabilities: a prior has one when it defines its members (no base class needed)
# ---------------------------------------------------------------------------------------------------------------

@runtime_checkable
class Summarizing(Protocol):
    """A prior with a per-frame summary of its per-particle state, recorded per frame as ``prior_summary``.

    ``summary_names``: the entries of the summary; ``summarize(state, weights)`` gives ``(len(summary_names),)``
    under the normalised ``weights`` ``(P,)``, or None when it has nothing to report. An optional
    ``summary_kind`` says what the summary is: ``"posterior"`` (the default: probabilities of the names, summing
    to 1, e.g. over a style label the particles carry) or ``"quantity"`` (posterior means of the named
    quantities, e.g. a pace in mm/frame).
    """

    summary_names: tuple[str, ...]

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None: ...


@runtime_checkable
class Labelling(Protocol):
    """A prior that names the model drawing the next poses when ``available`` history slots are real (one that
    grows its history through lower orders names the one in use); recorded per frame."""

    def label_for(self, available: int) -> str: ...


@runtime_checkable
class Restarting(Protocol):
    """A prior whose state after a lost frame is not simply :meth:`MotionPrior.start` from the last estimates
    (e.g. one whose state counts frames, or keeps a quantity of the person rather than of the lost frame)."""

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState: ...


@runtime_checkable
class Adopting(Protocol):
    """A prior whose state describes the newest pose (the step out of it, latent coordinates), and so must derive
    that state for particles arriving from another motion model of a composite prior."""

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState: ...


# The functions below look the optional members up by name: what ``isinstance(prior, Summarizing)`` checks, without
# its cost (several microseconds a call on Python 3.11) on every frame.

def summary_of(prior: MotionPrior) -> tuple[tuple[str, ...], str]:
    """The names of ``prior``'s per-frame summary and what it is (:class:`Summarizing`); no names and
    ``"posterior"`` for a prior without one."""
    names = getattr(prior, "summary_names", None)
    if names is None or not callable(getattr(prior, "summarize", None)):
        return (), "posterior"
    return tuple(names), getattr(prior, "summary_kind", "posterior")


def summarize(prior: MotionPrior, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
    """``prior``'s summary ``(len(names),)`` of the per-particle ``state`` under the normalised ``weights``
    ``(P,)``; None for a prior without one (:class:`Summarizing`)."""
    if getattr(prior, "summary_names", None) is None:
        return None
    own = getattr(prior, "summarize", None)
    return own(state, weights) if callable(own) else None


def label_for(prior: MotionPrior, available: int) -> str:
    """Which model of ``prior`` draws the next poses when ``available`` history slots are real: its own
    :class:`Labelling` answer, else its name."""
    own = getattr(prior, "label_for", None)
    return own(available) if callable(own) else prior.name


def restart(prior: MotionPrior, state: PriorState, recent: np.ndarray, n_particles: int,
            rng: np.random.Generator) -> PriorState:
    """Per-particle state after the filter lost the person and re-diffused around its last estimates ``recent``
    ``N x D``; ``state`` is the state the lost frame started from. The prior's own :class:`Restarting` answer,
    else :meth:`MotionPrior.start` from ``recent``."""
    own = getattr(prior, "restart", None)
    return own(state, recent, n_particles, rng) if callable(own) else prior.start(recent, n_particles, rng)


def adopt(prior: MotionPrior, state: PriorState, history: np.ndarray, available: int,
          rng: np.random.Generator) -> PriorState:
    """``prior``'s state for particles that arrive from another motion model of a composite prior: ``history``
    ``P x N x D`` their last poses (``N`` at least the prior's order, ``available`` of them real), ``state`` the
    rows the prior held at the positions they take. The prior's own :class:`Adopting` answer, else ``state``
    unchanged, which is right for a prior whose state does not describe the newest pose (none, or a slow quantity
    such as a pace or a height offset)."""
    own = getattr(prior, "adopt", None)
    return own(state, history, available, rng) if callable(own) else state
