"""The parts a learned prior is built from besides its model: small per-particle pieces with their own options.

A learned prior (CRBM, FCRBM, deep CRBM, GPDM) is a model that draws the next frame of the invariant features
(:mod:`tracker.core.representation`) from a batch of histories, plus some of these parts:

- :class:`GroundDiffusion`: Gaussian noise on each sample's ground position (mm), so that the likelihood can
  correct the drift of integrated velocities.
- :class:`PaceInput`: each particle's own pace (log ground speed), given to a model trained with a pace input.
- :class:`HeightOffset`: each particle's own root-height offset (mm), so that the images select the height of a
  shorter, taller or crouching person.
- :class:`PostureOffset`: one posture offset (rad) that integrates the images' corrections, so that the model
  stops pulling an unseen person's posture toward its training subjects'.
- :class:`GrowingModels`: the models of increasing order that grow the history from the known frames
  (Taylor 2009, Sec. 6.4).

Each part declares its options once (:attr:`OPTIONS`, used by the command line, experiment files and the API),
starts its per-particle state from the known frames, moves it one frame on, and summarises it under the
posterior weights. Its state lives in the prior's state dict under its own keys, rows on the leading axis, so
the filter's reindexing after resampling and the checkpoint carry it without the part's help. Every random
draw comes from the generator passed in, and a part with nothing to draw draws nothing.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Generic, Sequence, TypeVar

import numpy as np

from tracker.core.errors import InputError
from tracker.core.representation import PACE_FLOOR_MM, STANDING_LOG_PACE, log_pace, posture_features
from tracker.engine.registry import Option


def _check_range(what: str, value: float, low: float, high: float, unit: str) -> float:
    """``value`` as a float when ``low <= value <= high``; otherwise an :class:`InputError` saying so."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not low <= value <= high:
        raise InputError(f"{what} must lie in [{low:g}, {high:g}] {unit}, got {value!r}".rstrip())
    return float(value)


def gaussian_start(n_particles: int, std: float, rng: np.random.Generator) -> np.ndarray:
    """Each particle's initial value ``(P,)`` of a latent that starts at 0, Gaussian with std ``std`` (nothing
    drawn when 0)."""
    if std <= 0:
        return np.zeros(n_particles)
    return std * rng.standard_normal(n_particles)


def gaussian_drift(values: np.ndarray, std: float, rng: np.random.Generator) -> np.ndarray:
    """Per-particle values ``(P,)`` after one frame's random walk of std ``std`` (nothing drawn when 0)."""
    if std <= 0:
        return values
    return values + std * rng.standard_normal(len(values))


def shift_height(features: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Invariant features ``P x ... x K`` with the root height (feature 2, mm) of every frame moved by ``offset``
    ``(P,)`` mm, in place."""
    shape = (len(offset),) + (1,) * (features.ndim - 1)
    features[..., 2:3] += np.asarray(offset, float).reshape(shape)
    return features


#: Default ground-plane diffusion (mm per frame) of learned-prior samples. A learned prior predicts body-centred
#: motion; the ground position integrates its velocities, and a walker slightly faster or slower than the
#: training walks drifts away from particles that all move alike. Chosen for the CRBM on a validation render
#: (07_01 tracked with CRBMs trained on 07_02, 07_09, 07_10; 1000 particles, 4 views, 2 seeds): 0 mm gave
#: 41-71 mm error, 3 and 6 mm 16-18 mm, 12 mm 17-20 mm. The GPDM prior uses the same value.
ROOT_NOISE_MM = 5.0
#: Largest ground-plane diffusion (mm per frame) accepted.
MAX_ROOT_NOISE_MM = 1000.0


@dataclass(frozen=True)
class GroundDiffusion:
    """Gaussian noise of ``std_mm`` (mm per frame) on each sample's ground position (x, y)."""

    std_mm: float = ROOT_NOISE_MM

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("root_noise", float, ROOT_NOISE_MM, "ground-plane diffusion of each sample (mm per frame)",
               minimum=0.0, maximum=MAX_ROOT_NOISE_MM),)

    def __post_init__(self):
        object.__setattr__(self, "std_mm", _check_range("root noise", self.std_mm, 0.0, MAX_ROOT_NOISE_MM, "mm"))

    def apply(self, poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """``poses`` ``P x D`` with the noise added to the root's ground position, in place."""
        if self.std_mm > 0:
            self.apply_with(poses, rng.standard_normal((len(poses), 2)))
        return poses

    def apply_with(self, poses: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """``poses`` ``P x D`` moved by standard normal ``noise`` ``P x 2`` drawn beforehand, in place."""
        if self.std_mm > 0:
            poses[:, :2] += self.std_mm * noise
        return poses

    def settings(self) -> dict:
        return {"root_noise_mm": self.std_mm}


#: Defaults of the pace's spread and drift: the std of each particle's initial log pace around the known frames'
#: pace, and of its change per frame. Chosen a priori, before any tracking run: 0.3 covers a pace 0.55-1.8 times
#: the known frames' within two standard deviations; 0.05 per frame lets the pace move by about 0.4 (a factor
#: 1.5) in a second at 60 Hz, the time over which the training labels average.
PACE_SPREAD, PACE_DRIFT = 0.3, 0.05


@dataclass(frozen=True)
class PaceInput:
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
    SUMMARY: ClassVar[str] = "pace (mm/frame)"

    def __post_init__(self):
        object.__setattr__(self, "spread", _check_range("pace spread", self.spread, 0.0, 3.0, "(log units)"))
        object.__setattr__(self, "drift", _check_range("pace drift", self.drift, 0.0, 1.0, "(log units per frame)"))

    def start(self, step: np.ndarray, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """The state at the start from the pending root step ``step`` ``(3,)`` of the last known frame."""
        return {"pace": np.maximum(log_pace(step) + gaussian_start(n_particles, self.spread, rng),
                                   STANDING_LOG_PACE)}

    def advance(self, pace: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Each particle's log pace ``(P,)`` one frame on."""
        return np.maximum(np.array(gaussian_drift(pace, self.drift, rng), float), STANDING_LOG_PACE)

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The posterior mean ground speed (mm/frame) under the normalised ``weights`` ``(P,)``."""
        return float(np.sum(weights * (np.exp(state["pace"]) - PACE_FLOOR_MM)))

    def settings(self) -> dict:
        return {"pace_spread": self.spread, "pace_drift": self.drift}


@dataclass(frozen=True)
class HeightOffset:
    """Each particle's own root-height offset (mm; the person's root height minus the heights the model learned).
    State ``height_offset`` ``(P,)``: Gaussian with std ``spread`` (mm) at the start, a random walk of ``drift``
    (mm per frame). The prior shifts the history into the model's heights before the model sees it and the
    prediction back after."""

    spread: float = 0.0
    drift: float = 0.0

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("height_spread", float, 0.0, "std of each particle's offset between the person's root height and the "
               "heights the model learned, at the start (mm), so that the images select the height of a shorter, "
               "taller or crouching person", minimum=0.0, maximum=1000.0),
        Option("height_drift", float, 0.0, "std of each frame's random-walk step of the root-height offset (mm), so "
               "that it can follow a person who crouches or straightens up", minimum=0.0, maximum=100.0),
    )
    SUMMARY: ClassVar[str] = "height offset (mm)"

    def __post_init__(self):
        object.__setattr__(self, "spread", _check_range("height spread", self.spread, 0.0, 1000.0, "mm"))
        object.__setattr__(self, "drift", _check_range("height drift", self.drift, 0.0, 100.0, "mm per frame"))

    @property
    def active(self) -> bool:
        """Whether the particles carry offsets at all (a spread or a drift)."""
        return self.spread > 0 or self.drift > 0

    def start(self, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        return {"height_offset": gaussian_start(n_particles, self.spread, rng)}

    def advance(self, offset: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The offsets ``(P,)`` one frame on."""
        return gaussian_drift(offset, self.drift, rng)

    def advance_with(self, offset: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """The offsets one frame on for standard normal ``noise`` ``(P,)`` drawn beforehand."""
        return offset + self.drift * noise

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The posterior mean offset (mm) under the normalised ``weights`` ``(P,)``."""
        return float(np.sum(weights * state["height_offset"]))

    def settings(self) -> dict:
        return {"height_spread_mm": self.spread, "height_drift_mm": self.drift}


@dataclass(frozen=True)
class PostureOffset:
    """One posture offset (rad, the person's posture angles minus the ones the model would give) that moves each
    frame by ``gain`` times the images' mean correction (:meth:`updated`): an integrator of the likelihood's
    corrections, so that a model that pulls an unseen person's posture toward its training subjects' is
    corrected by as much as the images keep pulling it back. State ``posture_offset`` and ``posture_predicted``
    ``P x Kp`` (rows alike: the filter reindexes rows), the offset and the posture angles the prior predicted."""

    gain: float = 0.0

    OPTIONS: ClassVar[tuple[Option, ...]] = (
        Option("posture_gain", float, 0.0, "fraction per frame of the images' mean posture correction (posterior "
               "minus predicted mean posture angles) added to an offset by which the model's history and "
               "prediction are shifted", minimum=0.0, maximum=1.0),)
    SUMMARY: ClassVar[str] = "posture offset rms (deg)"

    def __post_init__(self):
        object.__setattr__(self, "gain", _check_range("posture gain", self.gain, 0.0, 1.0, "per frame"))

    def start(self, n_features: int, n_particles: int) -> dict[str, np.ndarray]:
        """No offset yet, and no prediction to measure the first correction against."""
        n_posture = len(posture_features(n_features))
        return {"posture_offset": np.zeros((n_particles, n_posture)),
                "posture_predicted": np.full((n_particles, n_posture), np.nan)}

    def restart(self, state: dict, new: dict, n_particles: int) -> dict:
        """``new`` (a fresh start) keeping the offset of ``state``: it is the person's, not the lost frame's."""
        return {**new, "posture_offset": np.repeat(np.asarray(state["posture_offset"])[:1], n_particles, axis=0)}

    def updated(self, state: dict, posterior: np.ndarray) -> np.ndarray:
        """The offset ``(Kp,)`` one frame on: moved by ``gain`` times the mean posture angles of the resampled
        particles ``posterior`` ``P x Kp`` minus the mean the prior predicted for them the frame before (NaN
        before the first prediction: no move)."""
        return updated_posture_offset(np.asarray(state["posture_offset"])[0], posterior,
                                      np.asarray(state["posture_predicted"])[0], self.gain)

    @staticmethod
    def state(offset: np.ndarray, predicted: np.ndarray, n_particles: int) -> dict[str, np.ndarray]:
        """The state entries for the offset ``(Kp,)`` and the predicted posture angles ``P x Kp``."""
        return {"posture_offset": np.repeat(offset[None], n_particles, axis=0),
                "posture_predicted": np.repeat(predicted.mean(axis=0)[None], n_particles, axis=0)}

    def summarize(self, state: dict, weights: np.ndarray) -> float:
        """The offset's RMS over the posture angles (degrees)."""
        return float(np.degrees(np.sqrt(np.mean(np.asarray(state["posture_offset"])[0] ** 2))))

    def settings(self) -> dict:
        return {"posture_gain": self.gain}


def updated_posture_offset(offset: np.ndarray, posterior: np.ndarray, predicted: np.ndarray,
                           gain: float) -> np.ndarray:
    """The posture offset ``(Kp,)`` moved by ``gain`` times the innovation, the mean of ``posterior`` ``P x Kp``
    minus ``predicted`` ``(Kp,)`` (NaN: no move)."""
    if not np.all(np.isfinite(predicted)):
        return offset
    return offset + gain * (posterior.mean(axis=0) - predicted)


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
