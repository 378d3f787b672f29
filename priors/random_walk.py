"""Hand-made smoothness priors: zero-velocity (first order) and constant-velocity (second order) random walks.

Zero velocity: ``x_t = x_{t-1} + N(0, diag(sigma^2))``. Constant velocity:
``x_t = x_{t-1} + damping (x_{t-1} - x_{t-2}) + N(0, diag(sigma^2))``. The
scale ``sigma`` is per pose number (mm or radians per frame) and comes either
from the user or from training clips at the tracking frame rate
(:func:`tracker.core.representation.step_rms`): the root-mean-square of the frame-to-frame changes, so the
random walk reaches the typical step, drift included.

The constant-velocity prior's defaults (``damping = 0.5``, the same noise as
the zero-velocity prior) were chosen on a synthetic render of the *training*
walk 07_01 with scales from 07_02, 07_09 and 07_10 (500 particles, 4 views, 2
seeds): undamped, or with the much smaller second-difference noise, each
particle's velocity keeps the noise that the likelihood selected it for and the
filter overshoots (170-380 mm error against 46-69 mm at these settings and
76-99 mm for zero velocity).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from tracker.core.errors import InputError
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.registry import Option, PriorContext, register_prior

#: Smallest per-dof noise (pose units per frame): dimensions the training clips never move still diffuse a little.
MIN_STD = 1e-4


def _check_std(std: np.ndarray, what: str) -> np.ndarray:
    std = np.asarray(std, float)
    if std.ndim != 1 or not np.all(np.isfinite(std)) or np.any(std < 0):
        raise InputError(f"{what} must be a vector of non-negative finite standard deviations, got {std}")
    return np.maximum(std, MIN_STD)


class ZeroVelocityPrior(MotionPrior):
    """First-order Gaussian random walk around each particle's last pose, with noise ``std`` ``(D,)`` (mm or
    radians per frame). ``prior_scale`` and ``isotropic_ground`` are the options ``std`` was made with
    (:func:`random_walk_std`), recorded in :meth:`settings`."""

    order = 1
    name = "zero-velocity"

    def __init__(self, std: np.ndarray, *, prior_scale: float = 1.0, isotropic_ground: bool = False):
        self.std = _check_std(std, "zero-velocity noise")
        self.prior_scale, self.isotropic_ground = prior_scale, isotropic_ground

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        last = history[:, -1]
        return last + rng.standard_normal(last.shape) * self.std, state

    def diffusion_std(self) -> np.ndarray:
        return self.std

    def settings(self) -> dict:
        return random_walk_settings(self)


class ConstantVelocityPrior(MotionPrior):
    """Second-order random walk: each particle keeps ``damping`` times its own last velocity, plus noise ``std``
    ``(D,)`` (mm or radians per frame; ``prior_scale`` and ``isotropic_ground`` as for :class:`ZeroVelocityPrior`).

    With only one known pose the velocity term is zero (the zero-velocity step).
    """

    order = 2
    name = "constant-velocity"

    def __init__(self, std: np.ndarray, damping: float = 0.5, *, prior_scale: float = 1.0,
                 isotropic_ground: bool = False):
        self.std = _check_std(std, "constant-velocity noise")
        if not 0.0 <= damping <= 1.0:
            raise InputError(f"damping must lie in [0, 1], got {damping}")
        self.damping = damping
        self.prior_scale, self.isotropic_ground = prior_scale, isotropic_ground

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        last = history[:, -1]
        step = rng.standard_normal(last.shape) * self.std
        if available >= 2:
            step += self.damping * (last - history[:, -2])
        return last + step, state

    def diffusion_std(self) -> np.ndarray:
        return self.std

    def settings(self) -> dict:
        return random_walk_settings(self)


def random_walk_settings(prior: ZeroVelocityPrior | ConstantVelocityPrior) -> dict:
    """A random-walk prior's options, under their names (its damping is a constant of the prior, not one)."""
    return {"prior_scale": prior.prior_scale, "isotropic_ground": prior.isotropic_ground}


SCALE_OPTION = Option("prior_scale", float, 1.0, "multiply the random-walk noise", minimum=0.0,
                      strict=True, maximum=1000.0)
ISOTROPIC_OPTION = Option("isotropic_ground", bool, False,
                          "give the root's two ground coordinates one noise, the RMS of their two scales, so the "
                          "walk does not favour the direction the training clips moved in",
                          default_note="off: a scale per axis; CMU's walks go along one axis")
#: The root's ground-plane coordinates (mm) in the 15-cone model's pose layout.
GROUND_DOFS = ("root_x", "root_y")


def isotropic_ground(std: np.ndarray, dof_names: Sequence[str], source: str | None = None) -> np.ndarray:
    """The per-dof scale ``std`` ``(D,)`` with both ground coordinates of the root set to their RMS,
    ``sqrt((s_x^2 + s_y^2) / 2)`` (mm per frame): the same spread of ground steps in every direction. Scales
    taken from clips that all move along one axis would otherwise let the random walk follow a person along
    that axis and hardly at all across it (the turned folds of docs/methods_report.md). A layout without ``root_x`` and ``root_y``
    is an :class:`InputError` naming ``source``."""
    names = list(dof_names)
    if not all(n in names for n in GROUND_DOFS):
        raise InputError(f"isotropic ground noise needs the root's ground coordinates {', '.join(GROUND_DOFS)}; "
                         f"this pose layout starts {', '.join(names[:6])}", source)
    idx = [names.index(n) for n in GROUND_DOFS]
    out = np.array(std, float)
    out[idx] = np.sqrt(np.mean(out[idx] ** 2))
    return out


def random_walk_std(context: PriorContext, options: dict) -> np.ndarray:
    """The random-walk priors' per-dof noise ``(D,)``: the context's RMS frame step times ``prior_scale``,
    with the ground coordinates made isotropic when ``isotropic_ground``."""
    std = context.step_std() * options["prior_scale"]
    if options["isotropic_ground"]:
        std = isotropic_ground(std, context.body_model.dof_names, context.source)
    return std


@register_prior("zero-velocity", summary="first-order Gaussian random walk (the baseline)",
                options=(SCALE_OPTION, ISOTROPIC_OPTION))
def build_zero_velocity(context: PriorContext, model_files: Sequence[Path], options: dict) -> ZeroVelocityPrior:
    return ZeroVelocityPrior(random_walk_std(context, options), prior_scale=options["prior_scale"],
                             isotropic_ground=options["isotropic_ground"])


@register_prior("constant-velocity", summary="second-order random walk keeping half of each particle's velocity",
                options=(SCALE_OPTION, ISOTROPIC_OPTION))
def build_constant_velocity(context: PriorContext, model_files: Sequence[Path], options: dict
                            ) -> ConstantVelocityPrior:
    return ConstantVelocityPrior(random_walk_std(context, options), prior_scale=options["prior_scale"],
                                 isotropic_ground=options["isotropic_ground"])
