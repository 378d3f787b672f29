"""The parts a learned prior is built from besides its model: small per-particle pieces with their own options.

A learned prior (CRBM, FCRBM, deep CRBM, GPDM, neural) is a model that draws the next frame of the invariant
features (:mod:`tracker.core.representation`) from a batch of histories, plus an ordered list of these parts
(:class:`priors.learned.LearnedPrior`, which declares them once: :class:`priors.learned.PartSpec`):

- :class:`PaceInput`: each particle's own pace (log ground speed), given to a model trained with a pace input.
- :class:`HeightOffset`: each particle's own root-height offset (mm), so that the images select the height of a
  shorter, taller or crouching person.
- :class:`PostureOffset`: one posture offset (rad) that integrates the images' corrections, so that the model
  stops pulling an unseen person's posture toward its training subjects'.
- :class:`GroundDiffusion`: Gaussian noise on each sample's ground position (mm), so that the likelihood can
  correct the drift of integrated velocities.

Every part implements one small protocol, :class:`Part`: it declares its options once (:attr:`Part.OPTIONS`, used
by the command line, experiment files and the API, and the bounds its constructor checks), starts its per-particle
state from the known frames, draws its random numbers for a step, updates from the weighted particles, conditions
the model's input, turns the model's draw into the proposal, and summarises its state under the posterior
weights. Its state lives in the prior's state dict under its own keys (:attr:`Part.KEYS`), rows on the leading
axis, so the filter's reindexing after resampling and its checkpoints carry it without the part's help. Every
random draw comes from the generator passed in, and a part with nothing to draw draws nothing.

:class:`GrowingModels` holds the models of increasing order that grow the history from the known frames
(Taylor 2009, Sec. 6.4).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Generic, Sequence, TypeVar

import numpy as np

from tracker.core.errors import InputError
from tracker.core.representation import (
    PACE_FLOOR_MM, STANDING_LOG_PACE, log_pace, pending_step, posture_features,
)
from tracker.engine.registry import Option


@dataclass
class Step:
    """One step of a learned prior for ``P`` particles as its parts see it; the parts change these in place.

    ``previous`` ``P x K``: the newest history frame's invariant features, with the root step each particle takes
    out of it (the resampled particles: the posterior the parts update from); ``history`` ``P x n x K``: the
    history's features (oldest first) that the model reads, which conditioning parts move into the frame the model
    knows (None for a model that reads none); ``inputs``: further model inputs ``P x C`` put before the history;
    ``model``: the model drawing this step; ``drawn`` ``P x K``: the next frame's features, once the model drew
    them; ``poses`` ``P x D``: the next poses, once integrated; ``new``: the next state's entries.
    """

    previous: np.ndarray
    history: np.ndarray | None
    model: Any
    inputs: list[np.ndarray] = field(default_factory=list)
    drawn: np.ndarray | None = None
    poses: np.ndarray | None = None
    new: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class Part:
    """The protocol of a learned prior's per-particle parts. A part is a frozen dataclass whose fields are the
    values of its :attr:`OPTIONS`, in order (checked against their bounds on construction; :meth:`settings` gives
    them under the options' names); each method below does nothing by default, and a part implements the ones it
    needs. A step of a learned prior calls, for its parts in order: :meth:`update`, :meth:`condition` (the model's
    input), then the model draws, then :meth:`propose` (the drawn features), the poses are integrated, and
    :meth:`displace` (the poses). The random numbers of a step are drawn first (:meth:`noise`): those of the
    parts that condition the model (:attr:`CONDITIONS`) in order, then the model's, then the others'."""

    #: The part's options, one per field in field order (the only place their defaults and bounds are written).
    OPTIONS: ClassVar[tuple[Option, ...]] = ()
    #: Units of the options, for messages.
    UNITS: ClassVar[tuple[str, ...]] = ()
    #: The state entries the part owns (one row per particle: reindexed and checkpointed with the filter's state).
    KEYS: ClassVar[tuple[str, ...]] = ()
    #: The name of the posterior mean :meth:`summarize` gives ("": none).
    SUMMARY: ClassVar[str] = ""
    #: Whether the part's random numbers are drawn before the model's (it moves the model's input) or after.
    CONDITIONS: ClassVar[bool] = True

    def __post_init__(self):
        for option, unit, f in zip(self.OPTIONS, self.UNITS, fields(self)):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
                    or not option.minimum <= value <= option.maximum:
                raise InputError(f"{option.name.replace('_', ' ')} must lie in [{option.minimum:g}, "
                                 f"{option.maximum:g}] {unit}, got {value!r}".rstrip())
            object.__setattr__(self, f.name, float(value))

    @property
    def active(self) -> bool:
        """Whether the part changes anything at these settings (a prior leaves an inactive part out of its steps,
        its state and its summary)."""
        return True

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """The part's state entries from the known frames ``n0 x D``."""
        return {}

    def restart(self, state: dict, started: dict, n_particles: int) -> dict[str, np.ndarray]:
        """The part's state entries after the filter lost the person and restarted: ``started`` is the fresh
        start's state (:meth:`start` from the last estimates), ``state`` the state the lost frame started from. By
        default the fresh start's; a part whose state is the person's rather than the lost frame's keeps it."""
        return {k: started[k] for k in self.KEYS}

    def noise(self, n_particles: int, rng: np.random.Generator) -> np.ndarray | None:
        """Every random number of one step, row ``i`` for particle ``i`` (None: nothing to draw)."""
        return None

    def update(self, state: dict, step: Step) -> None:
        """Update from the weighted particles (``step.previous``, resampled) before the model draws."""

    def condition(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """Move ``step.history`` into the frame the model knows, or add to ``step.inputs``."""

    def propose(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """Move the model's draw ``step.drawn`` back into the person's frame."""

    def displace(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """Move the integrated poses ``step.poses``."""

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The posterior mean of the :attr:`SUMMARY` quantity under the normalised ``weights`` ``(P,)``."""
        raise NotImplementedError(f"{type(self).__name__} has no summary")

    def settings(self) -> dict:
        """The part's option values under the options' names."""
        return {o.name: getattr(self, f.name) for o, f in zip(self.OPTIONS, fields(self))}


def gaussian_start(n_particles: int, std: float, rng: np.random.Generator) -> np.ndarray:
    """Each particle's initial value ``(P,)`` of a latent that starts at 0, Gaussian with std ``std`` (nothing
    drawn when 0)."""
    if std <= 0:
        return np.zeros(n_particles)
    return std * rng.standard_normal(n_particles)


def walk_noise(std: float, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray | None:
    """Standard normal numbers of ``shape`` for a random walk of std ``std`` (None, nothing drawn, when 0)."""
    return rng.standard_normal(shape) if std > 0 else None


def shift_height(features: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Invariant features ``P x ... x K`` with the root height (feature 2, mm) of every frame moved by ``offset``
    ``(P,)`` mm, in place."""
    shape = (len(offset),) + (1,) * (features.ndim - 1)
    features[..., 2:3] += np.asarray(offset, float).reshape(shape)
    return features


#: Defaults of the pace's spread and drift: the std of each particle's initial log pace around the known frames'
#: pace, and of its change per frame. Chosen a priori, before any tracking run: 0.3 covers a pace 0.55-1.8 times
#: the known frames' within two standard deviations; 0.05 per frame lets the pace move by about 0.4 (a factor
#: 1.5) in a second at 60 Hz, the time over which the training labels average.
PACE_SPREAD, PACE_DRIFT = 0.3, 0.05


@dataclass(frozen=True)
class PaceInput(Part):
    """Each particle's own pace (:func:`~tracker.core.representation.log_pace`), the input of a model trained with
    one (``train --pace-input``). State ``pace`` ``(P,)``: it starts at the known frames' pace with std
    ``spread`` (log units), moves by a random walk of ``drift`` per frame, and never falls below standing still
    (:data:`~tracker.core.representation.STANDING_LOG_PACE`)."""

    spread: float = PACE_SPREAD
    drift: float = PACE_DRIFT

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("pace_spread", float, PACE_SPREAD, "std of each particle's log pace around the known frames' pace "
               "at the start (models trained with a pace input)", minimum=0.0, maximum=3.0),
        Option("pace_drift", float, PACE_DRIFT, "std of the change of each particle's log pace per frame",
               minimum=0.0, maximum=1.0),
    )
    UNITS: ClassVar[tuple[str, ...]] = ("(log units)", "(log units per frame)")
    KEYS: ClassVar[tuple[str, ...]] = ("pace",)
    SUMMARY: ClassVar[str] = "pace (mm/frame)"

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Around the pace of the pending root step of the last known frame."""
        return {"pace": np.maximum(log_pace(pending_step(known)) + gaussian_start(n_particles, self.spread, rng),
                                   STANDING_LOG_PACE)}

    def noise(self, n_particles: int, rng: np.random.Generator) -> np.ndarray | None:
        return walk_noise(self.drift, (n_particles,), rng)

    def condition(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """The pace one frame on, given to the model before the history (it drifts first)."""
        pace = np.asarray(state["pace"], float)
        if noise is not None:
            pace = pace + self.drift * noise
        step.new["pace"] = np.maximum(pace, STANDING_LOG_PACE)
        step.inputs.append(step.model.pace_input(step.new["pace"]))

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The posterior mean ground speed (mm/frame) under the normalised ``weights`` ``(P,)``."""
        return float(np.sum(weights * (np.exp(state["pace"]) - PACE_FLOOR_MM)))


@dataclass(frozen=True)
class HeightOffset(Part):
    """Each particle's own root-height offset (mm; the person's root height minus the heights the model learned).
    State ``height_offset`` ``(P,)``: Gaussian with std ``spread`` (mm) at the start, a random walk of ``drift``
    (mm per frame). The history is shifted into the model's heights before the model sees it (a model that reads
    the history's features) and the model's draw back after."""

    spread: float = 0.0
    drift: float = 0.0

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("height_spread", float, 0.0, "std of each particle's offset between the person's root height and the "
               "heights the model learned, at the start (mm), so that the images select the height of a shorter, "
               "taller or crouching person", minimum=0.0, maximum=1000.0),
        Option("height_drift", float, 0.0, "std of each frame's random-walk step of the root-height offset (mm), so "
               "that it can follow a person who crouches or straightens up", minimum=0.0, maximum=100.0),
    )
    UNITS: ClassVar[tuple[str, ...]] = ("mm", "mm per frame")
    KEYS: ClassVar[tuple[str, ...]] = ("height_offset",)
    SUMMARY: ClassVar[str] = "height offset (mm)"

    @property
    def active(self) -> bool:
        """Whether the particles carry offsets at all (a spread or a drift)."""
        return self.spread > 0 or self.drift > 0

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        return {"height_offset": gaussian_start(n_particles, self.spread, rng)}

    def noise(self, n_particles: int, rng: np.random.Generator) -> np.ndarray | None:
        return walk_noise(self.drift, (n_particles,), rng)

    def condition(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """The offsets one frame on; the history at the heights the model knows."""
        offset = state["height_offset"]
        step.new["height_offset"] = offset if noise is None else offset + self.drift * noise
        if step.history is not None:
            shift_height(step.history, -step.new["height_offset"])

    def propose(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """The draw at the person's height."""
        shift_height(step.drawn, step.new["height_offset"])

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The posterior mean offset (mm) under the normalised ``weights`` ``(P,)``."""
        return float(np.sum(weights * state["height_offset"]))


@dataclass(frozen=True)
class PostureOffset(Part):
    """One posture offset (rad, the person's posture angles minus the ones the model would give) that moves each
    frame by ``gain`` times the images' mean correction (:meth:`update`): an integrator of the likelihood's
    corrections, so that a model that pulls an unseen person's posture toward its training subjects' is
    corrected by as much as the images keep pulling it back. State ``posture_offset`` and ``posture_predicted``
    ``P x Kp`` (rows alike: the filter reindexes rows), the offset and the posture angles the prior predicted."""

    gain: float = 0.0

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("posture_gain", float, 0.0, "fraction per frame of the images' mean posture correction (posterior "
               "minus predicted mean posture angles) added to an offset by which the model's history and "
               "prediction are shifted", minimum=0.0, maximum=1.0),)
    UNITS: ClassVar[tuple[str, ...]] = ("per frame",)
    KEYS: ClassVar[tuple[str, ...]] = ("posture_offset", "posture_predicted")
    SUMMARY: ClassVar[str] = "posture offset rms (deg)"

    @property
    def active(self) -> bool:
        return self.gain > 0

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """No offset yet, and no prediction to measure the first correction against."""
        n_posture = len(posture_features(np.shape(known)[-1]))
        return {"posture_offset": np.zeros((n_particles, n_posture)),
                "posture_predicted": np.full((n_particles, n_posture), np.nan)}

    def restart(self, state: dict, started: dict, n_particles: int) -> dict[str, np.ndarray]:
        """A fresh start keeping the offset of ``state``: it is the person's, not the lost frame's."""
        return {"posture_predicted": started["posture_predicted"],
                "posture_offset": np.repeat(np.asarray(state["posture_offset"])[:1], n_particles, axis=0)}

    def update(self, state: dict, step: Step) -> None:
        """The offset ``(Kp,)`` one frame on: moved by ``gain`` times the mean posture angles of the resampled
        particles minus the mean the prior predicted for them the frame before (NaN before the first prediction:
        no move)."""
        posture = posture_features(step.previous.shape[-1])
        offset = updated_posture_offset(np.asarray(state["posture_offset"])[0], step.previous[:, posture],
                                        np.asarray(state["posture_predicted"])[0], self.gain)
        step.new["posture_offset"] = np.repeat(offset[None], len(step.previous), axis=0)

    def condition(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """The history in the postures the model knows."""
        if step.history is not None:
            step.history[:, :, posture_features(step.history.shape[-1])] -= step.new["posture_offset"][0]

    def propose(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """The draw in the person's posture; its mean posture angles are what the next update measures against."""
        posture = posture_features(step.drawn.shape[-1])
        step.drawn[:, posture] += step.new["posture_offset"][0]
        step.new["posture_predicted"] = np.repeat(step.drawn[:, posture].mean(axis=0)[None], len(step.drawn), axis=0)

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The offset's RMS over the posture angles (degrees)."""
        return float(np.degrees(np.sqrt(np.mean(np.asarray(state["posture_offset"])[0] ** 2))))


def updated_posture_offset(offset: np.ndarray, posterior: np.ndarray, predicted: np.ndarray,
                           gain: float) -> np.ndarray:
    """The posture offset ``(Kp,)`` moved by ``gain`` times the innovation, the mean of ``posterior`` ``P x Kp``
    minus ``predicted`` ``(Kp,)`` (NaN: no move)."""
    if not np.all(np.isfinite(predicted)):
        return offset
    return offset + gain * (posterior.mean(axis=0) - predicted)


#: Default ground-plane diffusion (mm per frame) of learned-prior samples. A learned prior predicts body-centred
#: motion; the ground position integrates its velocities, and a walker slightly faster or slower than the
#: training walks drifts away from particles that all move alike. Chosen for the CRBM on a validation render
#: (07_01 tracked with CRBMs trained on 07_02, 07_09, 07_10; 1000 particles, 4 views, 2 seeds): 0 mm gave
#: 41-71 mm error, 3 and 6 mm 16-18 mm, 12 mm 17-20 mm. The GPDM prior uses the same value.
ROOT_NOISE_MM = 5.0


@dataclass(frozen=True)
class GroundDiffusion(Part):
    """Gaussian noise of ``std_mm`` (mm per frame) on each sample's ground position (x, y); its random numbers
    are drawn after the model's."""

    std_mm: float = ROOT_NOISE_MM

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("root_noise", float, ROOT_NOISE_MM, "ground-plane diffusion of each sample (mm per frame)",
               minimum=0.0, maximum=1000.0),)
    UNITS: ClassVar[tuple[str, ...]] = ("mm",)
    CONDITIONS: ClassVar[bool] = False

    def noise(self, n_particles: int, rng: np.random.Generator) -> np.ndarray | None:
        return walk_noise(self.std_mm, (n_particles, 2), rng)

    def displace(self, state: dict, step: Step, noise: np.ndarray | None) -> None:
        """The poses moved on the ground plane."""
        if noise is not None:
            step.poses[:, :2] += self.std_mm * noise


#: The order in which a learned prior's options list the shared parts' (:func:`priors.learned.part_options`): one
#: order on every prior's help, whatever the order its steps run its parts in.
OPTION_ORDER: tuple[type[Part], ...] = (GroundDiffusion, PaceInput, HeightOffset, PostureOffset)


M = TypeVar("M")


class GrowingModels(Generic[M]):
    """Models of increasing order (each with an ``order`` and, optionally, the lower-order ``growth`` models its
    file carries): the highest order whose history is all real poses draws the next frame, so a higher order
    starts by growing the history with lower ones (Taylor 2009, Sec. 6.4) and never runs on a padded history."""

    def __init__(self, models: Sequence[M], kind: str):
        if not models:
            raise InputError(f"the {kind} prior needs at least one model")
        orders = [m.order for m in models]
        if len(set(orders)) < len(orders):  # one would silently replace the other
            raise InputError(f"the {kind} prior takes one model per order (the lower orders grow the history), got "
                             f"orders {', '.join(map(str, orders))}; several model files all of one order make an "
                             "ensemble")
        by_order = {m.order: m for m in models}
        for m in models:  # the lower orders a model file carries, unless given explicitly
            for g in getattr(m, "growth", ()):
                by_order.setdefault(g.order, g)
        self.kind = kind
        self.models: list[M] = [by_order[o] for o in sorted(by_order)]
        first = self.models[0]
        for m in self.models[1:]:  # labels: a style-gated model's
            if (m.dof_names, m.body_model, getattr(m, "labels", None)) != \
                    (first.dof_names, first.body_model, getattr(first, "labels", None)) or abs(m.fps - first.fps) > 1e-6:
                raise InputError(f"{kind} models for one prior must share body model, pose layout, frame rate"
                                 f"{' and labels' if hasattr(first, 'labels') else ''}")

    @property
    def order(self) -> int:
        return self.models[-1].order

    @property
    def first(self) -> M:
        return self.models[0]

    def __iter__(self):
        return iter(self.models)

    def model_for(self, available: int) -> M:
        """The highest-order model whose history is all real poses."""
        usable = [m for m in self.models if m.order <= available]
        if not usable:
            hint = " (train embeds one; or pass --model crbm1.pt crbmN.pt)" if self.kind == "CRBM" else \
                " (train embeds one)"
            raise InputError(f"the {self.kind} of order {self.models[0].order} needs {self.models[0].order} known "
                             f"frame(s), {available} given: give more known frames or a lower-order model to "
                             f"grow from{hint}")
        return usable[-1]
