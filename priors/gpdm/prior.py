"""The GPDM motion prior: a GPDM (:mod:`priors.gpdm.model`) drawing each particle's next latent point and pose,
plus the parts of :mod:`priors.parts`. Registered as ``gpdm`` (``train`` and ``track --prior gpdm``)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from priors.common import loaded, source_of
from priors.gpdm.subset import MIN_STRETCH
from priors.settings import AUTO_INDUCING, DYNAMICS, EXACT_MAX_FRAMES, GPDM_MAX_FRAMES, MAX_LATENT_NOISE, GPDMConfig
from priors.learned import LearnedPrior, PartSpec, SmallModel, part_options, resolve_parts
from priors.parts import GroundDiffusion, HeightOffset, Part, PostureOffset, Step
from tracker.core.errors import InputError
from tracker.core.representation import STEP_FEATURES, pending_step, poses_to_invariant
from tracker.engine.prior import PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # the model and torch load when the prior is built or trained, not when it registers
    import torch

    from priors.gpdm.model import GPDMPriorModel


#: Default height spread (mm) of the GPDM prior: each particle's own root-height offset, Gaussian with this std at
#: the start. It won against none on the leave-one-subject-out protocol's tuning folds (mean ratio to the baseline
#: over both view counts 0.75 against 0.88) and test folds (1.42 against 1.73; with 4 views 0.88 against 1.48;
#: docs/methods_report.md); the CRBM's value, not tuned again for the GPDM.
HEIGHT_SPREAD = 50.0


class GPDMPrior(LearnedPrior):
    """Samples every particle's next pose through the GPDM, in one batch: a model plus parts.

    Each particle carries its latent history (``order`` points) and the pending root step of its newest
    frame (see :class:`priors.conditional.ConditionalPrior` for why). A step draws the next latent point from the
    dynamics GP, mean plus ``noise_scale`` times the predictive standard deviation; the observation GP's mean gives
    the new frame's invariant features; the root moves by the pending step. Initial latent points are the
    projections of the known poses. The parts, in the order of :attr:`PARTS` (:mod:`priors.parts`; the model reads
    no history features, so they move only its prediction), each given as a keyword under its name (None or
    absent: from ``options``, the registered builder's option values, else its default;
    :func:`~priors.learned.resolve_parts`): ``ground`` (:class:`~priors.parts.GroundDiffusion`); ``height``
    (:class:`~priors.parts.HeightOffset`; by default a spread of :data:`HEIGHT_SPREAD`; ``HeightOffset(0)`` turns
    it off), each particle's own root-height offset added to the heights the observation GP predicts; ``posture``
    (:class:`~priors.parts.PostureOffset`, off by default), an offset added to the predicted posture angles that
    integrates the images' corrections.
    """

    name = "gpdm"
    order = 1
    reads_history = False
    PARTS: ClassVar[tuple[PartSpec, ...]] = (
        PartSpec("ground", GroundDiffusion),
        PartSpec("height", HeightOffset, defaults={"height_spread": HEIGHT_SPREAD}),
        PartSpec("posture", PostureOffset))
    SMALL_MODELS: ClassVar[tuple[SmallModel, ...]] = (SmallModel({"iterations": 3}),)

    def __init__(self, model: GPDMPriorModel, noise_scale: float = 1.0, *, dtype: torch.dtype | None = None,
                 options: Mapping[str, Any] | None = None, **parts: Part | None):
        import torch

        from priors.gpdm.predict import prepare

        if not noise_scale >= 0:
            raise InputError("GPDM latent noise must be non-negative")
        super().__init__(resolve_parts(self.PARTS, options=options, given=parts, kind="GPDM"))
        self.model = model
        self.predictor = prepare(model.gpdm)
        self.sampler = self.predictor.sampler(torch.float32 if dtype is None else dtype)
        self.latent_order = model.gpdm.config.order
        self.noise_scale = float(noise_scale)

    def settings(self) -> dict:
        return {"latent_noise": self.noise_scale, **super().settings()}

    def latent_history(self, poses: np.ndarray) -> np.ndarray:
        """The latent state ``P x (o d)`` (newest first, ``o`` the latent order) of pose sequences ``P x n x D``
        (oldest first): the projections of their last ``o`` poses' features, the earliest pose repeated when
        ``n < o``."""
        import torch

        o, P = self.latent_order, len(poses)
        recent = poses[:, -o:] if poses.shape[1] >= o else \
            np.concatenate([np.repeat(poses[:, :1], o - poses.shape[1], axis=1), poses], axis=1)
        feats = poses_to_invariant(np.concatenate([recent[:, :1], recent], axis=1))[:, 1:]  # P x o x K
        flat = self.model.normaliser.transform(feats.reshape(P * o, -1))
        latent = self.predictor.project(torch.tensor(flat)).numpy().reshape(P, o, -1)
        return latent[:, ::-1].reshape(P, -1)

    def model_state(self, known: np.ndarray, n_particles: int) -> PriorState:
        """The latent history of the known frames and the pending step of the last one."""
        return {"latent": np.repeat(self.latent_history(known[None]), n_particles, axis=0),
                "step": np.repeat(pending_step(known)[None], n_particles, axis=0)}

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """The state of particles arriving from another motion model: the latent coordinates and the step of
        their own recent poses; the height offsets those positions held."""
        real = history[:, history.shape[1] - available:]
        return {**state, "latent": self.latent_history(real), "step": pending_step(real[:, -2:])}

    def model_noise(self, n_particles: int, available: int, rng: np.random.Generator) -> np.ndarray:
        """Standard normal latent noise ``P x d``."""
        return rng.standard_normal((n_particles, self.model.gpdm.config.latent_dim))

    def prepare(self, history: np.ndarray, available: int, state: PriorState) -> Step:
        """The pending step of each particle's newest frame; with a posture offset, that frame's features too
        (the posterior the offset updates from). The model reads no history features."""
        if self.part("posture") is not None:
            previous = poses_to_invariant(history[:, -2:] if history.shape[1] > 1 else
                                          np.concatenate([history[:, :1], history], axis=1))[:, -1]
        else:
            previous = np.zeros((len(history), history.shape[-1]))
        previous[:, list(STEP_FEATURES)] = state["step"]
        return Step(previous=previous, history=None, model=self.model)

    def predict(self, step: Step, state: PriorState, noise: np.ndarray) -> np.ndarray:
        """The observation GP's mean at the next latent point (mean plus ``noise_scale`` times the predictive
        standard deviation of the dynamics GP, for the standard normal ``noise``); the latent history moves on."""
        import torch

        x, pose_features = self.sampler.step(torch.from_numpy(np.ascontiguousarray(state["latent"])),
                                             torch.from_numpy(noise), self.noise_scale)
        x = x.numpy()
        d = self.model.gpdm.config.latent_dim
        step.new["latent"] = np.concatenate([x, state["latent"][:, :-d]], axis=1) if self.latent_order > 1 else x
        return self.model.normaliser.inverse(pose_features.numpy())

    def diffusion_std(self) -> np.ndarray:
        return self.model.pose_step_rms


# ---------------------------------------------------------------------------
# Registration: building from a model file, training from clips
# ---------------------------------------------------------------------------

def train_gpdm_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                         progress: Callable[[int, int, dict], None] | None = None,
                         checkpoint: Path | None = None, resume: bool = False) -> GPDMPriorModel:
    """``train --prior gpdm``: :func:`priors.gpdm.training.train_gpdm_from_data` (imported, with torch, when
    called)."""
    from priors.gpdm.training import train_gpdm_from_data

    return train_gpdm_from_data(data, options, rng, progress, checkpoint, resume)


GPDM_TRAIN_OPTIONS = (
    Option("latent_dim", int, GPDMConfig.latent_dim, "latent dimensions", minimum=1),
    Option("dynamics", str, GPDMConfig.dynamics, "dynamics kernel", choices=DYNAMICS),
    Option("order", int, GPDMConfig.order, "dynamics order 1 or 2", choices=(1, 2)),
    Option("balance", float, GPDMConfig.balance,
           "exponent M of the prior on the observation hyperparameters", minimum=0.0, strict=True),
    Option("iterations", int, GPDMConfig.iterations, "L-BFGS iterations", minimum=1),
    Option("inducing", int, GPDMConfig.inducing,
           "inducing frames of the sparse GPs, chosen by farthest-point sampling; 0 = exact", minimum=0,
           default_note=f"exact up to {EXACT_MAX_FRAMES} training frames, {AUTO_INDUCING} above"),
    Option("max_frames", int, GPDM_MAX_FRAMES, "most training frames: a larger corpus is cut to one stretch of "
           "consecutive frames per clip (clips drawn in turn from every folder where they do not all fit), chosen "
           "with --seed and listed in the model file", minimum=MIN_STRETCH),
    Option("checkpoint_every", int, None, "also save the training state every this many iterations (at the end of "
                                          "the L-BFGS chunk reaching them), for train --resume", minimum=1),
)


@register_prior(
    "gpdm", summary="Gaussian Process Dynamical Model (Wang 2005), latent coordinates carried per particle",
    model_files="one", train=train_gpdm_from_data, train_options=GPDM_TRAIN_OPTIONS, resumable=True,
    options=(Option("latent_noise", float, 1.0,
                    "multiple of the predictive standard deviation added to each latent step",
                    minimum=0.0, maximum=MAX_LATENT_NOISE),
             *part_options(GPDMPrior.PARTS)))
def build_gpdm(context: PriorContext, model_files: Sequence[Path], options: dict) -> GPDMPrior:
    from priors.gpdm.file import load_gpdm_prior
    from priors.gpdm.model import GPDMPriorModel

    model = loaded(model_files[0], load_gpdm_prior, GPDMPriorModel, "GPDM")
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps,
                           source_of(model_files[0]))
    try:
        return GPDMPrior(model, options["latent_noise"], options=options)
    except InputError as exc:  # a kernel matrix of the file's hyperparameters that is not positive definite
        if exc.path is not None:
            raise
        raise InputError(f"GPDM model: {exc.reason}", source_of(model_files[0])) from None
