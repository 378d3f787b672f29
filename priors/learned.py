"""A learned prior: a model plus an ordered list of parts (:mod:`priors.parts`).

:class:`LearnedPrior` runs the parts' protocol (:class:`priors.parts.Part`) around a model; a family of learned
priors implements four methods: :meth:`~LearnedPrior.model_state` (the model's own per-particle state from the
known frames), :meth:`~LearnedPrior.model_noise` (the model's random numbers of one step) and
:meth:`~LearnedPrior.prepare` / :meth:`~LearnedPrior.predict` (what the model reads, and its draw). A step draws
every random number first, in one order for every learned prior: the parts that condition the model, in list
order (:attr:`~priors.parts.Part.CONDITIONS`, where the model reads the history's features:
:attr:`LearnedPrior.reads_history`), then the model, then the other parts; so a particle's numbers are those at
its row whatever the batch.

A learned prior declares its parts once, as :class:`PartSpec` entries of :attr:`LearnedPrior.PARTS`, in the order
its steps run them. From that one declaration :func:`part_options` gives the options its registration declares,
:func:`resolve_parts` turns the options (or parts given to the constructor) into the parts in that order,
:meth:`LearnedPrior.part` finds a part in use by its name, and the contract tests enumerate the parts and the
small models (:attr:`LearnedPrior.SMALL_MODELS`) of every registered learned prior.
"""
from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Mapping, Sequence, TypeVar

import numpy as np

from priors.parts import OPTION_ORDER, Part, Step
from tracker.core.errors import InputError
from tracker.core.representation import STEP_FEATURES, next_poses
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.registry import Option

P = TypeVar("P", bound=Part)


#: What the help says of an option whose default depends on whether the model takes a pace input.
PACED_DEFAULT = "{paced:g} for a model trained with a pace input, 0 otherwise"


def is_paced(model: Any) -> bool:
    """Whether ``model`` takes a pace input (its ``pace_label`` is set: ``train --pace-input``)."""
    return getattr(model, "pace_label", None) is not None


@dataclass(frozen=True)
class PartSpec:
    """One part a learned prior declares (:attr:`LearnedPrior.PARTS`): the name its constructor takes the part
    under and :meth:`LearnedPrior.part` finds it by (``name``), its type (``kind``), and where the defaults of its
    options differ from the part's own: ``defaults`` (option name -> value) for every model, ``paced_defaults`` for
    a model trained with a pace input (such an option is unset by default, its help saying so, and a model without
    a pace input takes the part's own default). ``paced``: the part is there exactly when the model takes a pace
    input (:func:`is_paced`), and its options, unset by default, are refused for a model without one."""

    name: str
    kind: type[Part]
    defaults: Mapping[str, float] = field(default_factory=dict)
    paced_defaults: Mapping[str, float] = field(default_factory=dict)
    paced: bool = False

    def options(self) -> tuple[Option, ...]:
        """The part's options as the prior declares them, with the prior's defaults."""
        out = []
        for option in self.kind.OPTIONS:
            if self.paced:
                option = replace(option, default=None, default_note=f"{option.default:g}")
            elif option.name in self.paced_defaults:
                option = replace(option, default=None,
                                 default_note=PACED_DEFAULT.format(paced=self.paced_defaults[option.name]))
            elif option.name in self.defaults:
                option = replace(option, default=self.defaults[option.name])
            out.append(option)
        return tuple(out)

    def build(self, values: Mapping[str, Any], paced: bool) -> Part:
        """The part of the option ``values`` (option name -> value; a missing or None value takes the prior's
        default for a model with, ``paced``, or without a pace input)."""
        defaults = {o.name: o.default for o in self.kind.OPTIONS}
        defaults.update(self.defaults)
        if paced:
            defaults.update(self.paced_defaults)
        return self.kind(*(defaults[o.name] if values.get(o.name) is None else values[o.name]
                           for o in self.kind.OPTIONS))


def part_options(specs: Sequence[PartSpec]) -> tuple[Option, ...]:
    """The options of a learned prior's parts ``specs``, as its registration declares them: the shared parts' in
    :data:`~priors.parts.OPTION_ORDER` (one order on every prior's help, whatever the order its steps run the
    parts in), then any other part's in declared order."""
    rank = {kind: i for i, kind in enumerate(OPTION_ORDER)}
    ordered = sorted(specs, key=lambda s: rank.get(s.kind, len(rank)))  # stable: the others keep their order
    return tuple(o for spec in ordered for o in spec.options())


def resolve_parts(specs: Sequence[PartSpec], *, paced: bool = False, options: Mapping[str, Any] | None = None,
                  given: Mapping[str, Part | None] | None = None, kind: str = "learned prior") -> tuple[Part, ...]:
    """The parts of a learned prior, in the order of its ``specs`` (:attr:`LearnedPrior.PARTS`; the order its
    steps run them and draw their random numbers in). Each spec's part is the one ``given`` under its name (the
    constructor's keywords; None or absent: unset), else that of its option values in ``options`` (a registered
    builder's resolved options; unset values take the defaults), else its default for the model. A ``paced``
    spec's part is there exactly when the model takes a pace input (``paced``); a pace part or pace option given
    for a model without one is refused, as is a model with a pace input for a prior that declares none
    (:class:`InputError`, naming the model's ``kind``), and a part no spec names (:class:`TypeError`)."""
    given = {k: v for k, v in (given or {}).items()}
    options = options or {}
    names = [s.name for s in specs]
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise TypeError(f"the {kind} prior takes the parts {', '.join(names)}, not {', '.join(unknown)}")
    if paced and not any(s.paced for s in specs):
        raise InputError(f"this prior takes no pace input, and this {kind} was trained with one")
    parts = []
    for spec in specs:
        part = given.get(spec.name)
        values = {o.name: options.get(o.name) for o in spec.kind.OPTIONS}
        if spec.paced and not paced:
            if part is not None:
                raise InputError(f"the {spec.name} settings are for a {kind} trained with a pace input (train "
                                 "--pace-input); this one has none")
            set_values = [name for name, value in values.items() if value is not None]
            if set_values:
                raise InputError(f"{', '.join(n.replace('_', ' ') for n in set_values)} applies to a model trained "
                                 "with a pace input (train --pace-input); this one has none")
            continue
        if part is not None and not isinstance(part, spec.kind):
            raise TypeError(f"the {kind} prior's {spec.name} part is a {spec.kind.__name__}, got "
                            f"{type(part).__name__}")
        parts.append(spec.build(values, paced) if part is None else part)
    return tuple(parts)


@dataclass(frozen=True)
class SmallModel:
    """A model of a learned prior that trains in seconds, which its contract tests build it from
    (tests/priors/test_prior_contract.py): the training ``options`` on the first ``clips`` of the tests' walks (of
    different people, so that their paces vary); ``label`` tells the models of one prior apart."""

    options: Mapping[str, Any]
    clips: int = 1
    label: str = ""


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
    #: The parts the prior takes, declared once, in the order its steps run them (which fixes the order of their
    #: random draws): its options (:func:`part_options`), its constructor's keywords and :meth:`part`'s names.
    PARTS: ClassVar[tuple[PartSpec, ...]] = ()
    #: Small models the prior's contract tests train and build it from.
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = ()

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

    def part(self, which: str | type[P]) -> Part | None:
        """The part in use declared under the name ``which`` (:attr:`PARTS`: ``prior.part("height")``), or of the
        type ``which``; None if there is none in use. A name the prior does not declare is a :class:`KeyError`."""
        if isinstance(which, str):
            spec = next((s for s in self.PARTS if s.name == which), None)
            if spec is None:
                raise KeyError(f"{self.name} declares no part {which!r} (its parts: "
                               f"{', '.join(s.name for s in self.PARTS)})")
            which = spec.kind
        return next((p for p in self.parts if isinstance(p, which)), None)

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
