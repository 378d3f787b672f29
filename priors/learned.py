"""A learned prior: a model plus an ordered list of parts (:mod:`priors.parts`).

:class:`LearnedPrior` runs the parts' protocol (:class:`priors.parts.Part`) around a model; a family of learned
priors implements four methods: :meth:`~LearnedPrior.model_state` (the model's own per-particle state from the
known frames), :meth:`~LearnedPrior.model_noise` (the model's random numbers of one step) and
:meth:`~LearnedPrior.prepare` / :meth:`~LearnedPrior.predict` (what the model reads, and its draw). A step draws
every random number first, in one order for every learned prior: the parts that condition the model, in list
order (:attr:`~priors.parts.Part.CONDITIONS`, where the model reads the history's features:
:attr:`LearnedPrior.reads_history`), then the model, then the other parts; so a particle's numbers are those at
its row whatever the batch.
"""
from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass
from typing import Any, Sequence, TypeVar

import numpy as np

from priors.parts import GroundDiffusion, HeightOffset, PaceInput, Part, PostureOffset, Step
from tracker.core.representation import STEP_FEATURES, next_poses
from tracker.engine.prior import MotionPrior, PriorState

P = TypeVar("P", bound=Part)


@dataclass
class StepNoise:
    """Every random number of one step: the model's and each part's (None where a part draws nothing)."""

    model: Any
    parts: list[np.ndarray | None]


class LearnedPrior(MotionPrior):
    """A model plus ``parts`` (:class:`~priors.parts.Part`), in order. Parts that change nothing at their settings
    (:attr:`~priors.parts.Part.active`) take no part in the steps, the state or the summary, but their settings
    are recorded. Per-particle state: the model's (:meth:`model_state`, which includes ``step``, the pending root
    step of the newest history frame) and the parts' entries."""

    #: Whether the model reads the history's features (which the conditioning parts move); a model that does not
    #: (the GPDM: latent coordinates) draws its random numbers before every part's.
    reads_history: bool = True

    def __init__(self, parts: Sequence[Part]):
        #: Every part given, in order, in use or not.
        self.configured: tuple[Part, ...] = tuple(parts)
        #: The parts in use, in order.
        self.parts: tuple[Part, ...] = tuple(p for p in self.configured if p.active)
        self.summary_names = tuple(p.SUMMARY for p in self.parts if p.SUMMARY)

    @property
    def summary_kind(self) -> str:
        """``"quantity"``: the summary is the posterior means of the parts' quantities."""
        return "quantity" if self.summary_names else "posterior"

    def part(self, kind: type[P]) -> P | None:
        """The part in use of type ``kind`` (None if there is none)."""
        return next((p for p in self.parts if isinstance(p, kind)), None)

    @property
    def ground(self) -> GroundDiffusion | None:
        """The ground diffusion in use (None: none)."""
        return self.part(GroundDiffusion)

    @property
    def pace(self) -> PaceInput | None:
        """The pace input in use (None: none; a model trained without one takes none)."""
        return self.part(PaceInput)

    @property
    def height(self) -> HeightOffset | None:
        """The root-height offset in use (None: none)."""
        return self.part(HeightOffset)

    @property
    def posture(self) -> PostureOffset | None:
        """The posture offset in use (None: none)."""
        return self.part(PostureOffset)

    # -- what a family of learned priors implements --------------------------------------------------------------

    @abstractmethod
    def model_state(self, known: np.ndarray, n_particles: int) -> PriorState:
        """The model's own state entries from the known frames ``n0 x D`` (no random draws)."""

    @abstractmethod
    def model_noise(self, n_particles: int, available: int, rng: np.random.Generator) -> Any:
        """The model's random numbers for one step of ``n_particles`` particles."""

    @abstractmethod
    def prepare(self, history: np.ndarray, available: int, state: PriorState) -> Step:
        """The step's :class:`~priors.parts.Step`: the newest frame's features with each particle's pending step,
        and the history's features where the model reads them."""

    @abstractmethod
    def predict(self, step: Step, state: PriorState, noise: Any) -> np.ndarray:
        """The model's draw ``P x K`` (invariant features) for the conditioned ``step``, from its ``noise``;
        the model's own next state entries go to ``step.new``."""

    # -- the protocol ---------------------------------------------------------------------------------------------

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        known = np.atleast_2d(np.asarray(known, float))
        state = self.model_state(known, n_particles)
        for part in self.parts:
            state.update(part.start(known, n_particles, rng))
        return state

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState:
        """:meth:`start` from ``recent``, each part keeping what it keeps (:meth:`~priors.parts.Part.restart`)."""
        new = self.start(recent, n_particles, rng)
        for part in self.parts:
            new.update(part.restart(state, new, n_particles))
        return new

    def step_noise(self, n_particles: int, available: int, rng: np.random.Generator) -> StepNoise:
        """Every random number of one step, in the order of the module docstring; particle ``i`` uses row ``i``."""
        before = [p.CONDITIONS and self.reads_history for p in self.parts]
        parts: list[np.ndarray | None] = [p.noise(n_particles, rng) if b else None for p, b in zip(self.parts, before)]
        model = self.model_noise(n_particles, available, rng)
        for i, p in enumerate(self.parts):
            if not before[i]:
                parts[i] = p.noise(n_particles, rng)
        return StepNoise(model, parts)

    def advance(self, history: np.ndarray, available: int, state: PriorState,
                noise: StepNoise) -> tuple[np.ndarray, PriorState]:
        """The step of :meth:`sample` for given ``noise`` (:meth:`step_noise`): deterministic."""
        step = self.prepare(history, available, state)
        for part in self.parts:
            part.update(state, step)
        for part, z in zip(self.parts, noise.parts):
            part.condition(state, step, z)
        step.drawn = self.predict(step, state, noise.model)
        for part, z in zip(self.parts, noise.parts):
            part.propose(state, step, z)
        step.poses = next_poses(history[:, -1], step.previous, step.drawn)
        for part, z in zip(self.parts, noise.parts):
            part.displace(state, step, z)
        step.new["step"] = step.drawn[:, list(STEP_FEATURES)]
        return step.poses, step.new

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        return self.advance(history, available, state, self.step_noise(len(history), available, rng))

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        """The posterior means of :attr:`summary_names` (the parts' quantities, e.g. the pace); None when no part
        has one."""
        values = [p.summarize(state, weights) for p in self.parts if p.SUMMARY]
        return np.array(values) if values else None

    def settings(self) -> dict:
        out: dict = {}
        for part in self.configured:
            out.update(part.settings())
        return out
