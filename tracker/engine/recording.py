"""What the filter records per frame, chosen by the caller (the "collectors" of nchopin/particles).

The engine hands every tracked frame's :class:`FrameStep` to a
:class:`Recording`; a recording keeps one list per requested quantity and
stacks them at the end. Quantities are named (see :data:`RECORDERS`) or given
as ``{name: function(step)}`` for anything else.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from tracker.core.errors import InputError
from tracker.engine.weights import LogWeights


@dataclass(frozen=True)
class FrameStep:
    """One tracked frame as the filter left it.

    ``particles`` ``P x D`` and ``weights`` are the weighted particles before
    resampling; ``mean`` and ``best`` ``(D,)`` the weighted mean and the
    highest-weight particle; ``ess`` the effective sample size before
    resampling; ``recovered`` is true when no particle explained the frame and
    the filter re-diffused around its last estimate. ``seconds`` times the
    frame's stages: ``load`` (reading the frame), ``observe`` (the
    likelihood's per-frame preparation) and ``filter`` (prior, likelihood,
    resampling); :meth:`ParticleFilter.run <tracker.engine.filter.ParticleFilter.run>` adds ``wall``, the time
    the frame added to the run (less than the sum of the others where reading and filtering overlap).
    ``prior_label`` names the model that drew the frame's poses; ``prior_summary`` is the prior's
    summary of its per-particle state under the weights (:func:`~tracker.engine.prior.summarize`),
    or None.
    """

    index: int
    frame: int
    particles: np.ndarray
    weights: LogWeights
    mean: np.ndarray
    best: np.ndarray
    ess: float
    resampled: bool
    recovered: bool
    seconds: Mapping[str, float]
    prior_label: str = ""
    prior_summary: np.ndarray | None = None


#: The stages a frame's time is split into (:attr:`FrameStep.seconds`); without overlap its wall time is their sum.
STAGES = ("load", "observe", "filter")

#: Named per-frame quantities.
RECORDERS: dict[str, Callable[[FrameStep], Any]] = {
    "mean_poses": lambda s: s.mean,
    "best_poses": lambda s: s.best,
    "ess": lambda s: s.ess,
    "resampled": lambda s: s.resampled,
    "recovered": lambda s: s.recovered,
    "load_seconds": lambda s: s.seconds["load"],
    "observe_seconds": lambda s: s.seconds["observe"],
    "filter_seconds": lambda s: s.seconds["filter"],
    "wall_seconds": lambda s: s.seconds.get("wall", sum(s.seconds[k] for k in STAGES)),
    "prior_labels": lambda s: s.prior_label,
    "prior_summary": lambda s: s.prior_summary,
    "particles": lambda s: s.particles,
    "weights": lambda s: s.weights.normalised,
}

#: What :func:`tracker.track` records unless told otherwise (particles and weights are large: ask for them).
DEFAULT_RECORD = ("mean_poses", "best_poses", "ess", "resampled", "recovered", "load_seconds", "observe_seconds",
                  "filter_seconds", "wall_seconds", "prior_labels")


class Recording:
    """Collects the requested quantities of every :class:`FrameStep`."""

    def __init__(self, record: Iterable[str] | Mapping[str, Callable[[FrameStep], Any]] = DEFAULT_RECORD):
        if isinstance(record, Mapping):
            self.functions = dict(record)
        else:
            unknown = [n for n in record if n not in RECORDERS]
            if unknown:
                raise InputError(f"unknown recorded quantity {', '.join(map(repr, unknown))}; choose from "
                                 f"{', '.join(RECORDERS)} or pass {{name: function(step)}}")
            self.functions = {n: RECORDERS[n] for n in record}
        self.values: dict[str, list] = {n: [] for n in self.functions}

    def add(self, step: FrameStep) -> None:
        for name, f in self.functions.items():
            self.values[name].append(f(step))

    def result(self) -> dict[str, np.ndarray]:
        """One array per quantity, frames on the leading axis."""
        return {name: np.array(v) for name, v in self.values.items()}
