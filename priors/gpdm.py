"""The GPDM motion prior: a GPDM (:mod:`priors.gpdm_model`) drawing each particle's next latent point and pose,
plus the parts of :mod:`priors.parts`. Registered as ``gpdm`` (``train`` and ``track --prior gpdm``)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from priors.common import loaded, read_model_file, source_of, torch_save_atomic
from priors.settings import AUTO_INDUCING, DYNAMICS, EXACT_MAX_FRAMES, MAX_LATENT_NOISE, GPDMConfig
from priors.parts import GroundDiffusion, HeightOffset, shift_height
from tracker.core.errors import InputError
from tracker.core.representation import STEP_FEATURES, next_poses, pending_step, poses_to_invariant
from tracker.engine.prior import MotionPrior, PriorState
from tracker.engine.registry import Option, PriorContext, TrainingData, register_prior

if TYPE_CHECKING:  # the model and torch load when the prior is built or trained, not when it registers
    import torch

    from priors.gpdm_model import GPDM
    from priors.gpdm_training import GPDMCheckpoint, GPDMPriorModel


#: Default height spread (mm) of the GPDM prior: each particle's own root-height offset, Gaussian with this std at
#: the start. It won against none on the leave-one-subject-out protocol's tuning folds (mean ratio to the baseline
#: over both view counts 0.75 against 0.88) and test folds (1.42 against 1.73; with 4 views 0.88 against 1.48;
#: docs/methods_report.md); the CRBM's value, not tuned again for the GPDM.
HEIGHT_SPREAD = 50.0


class GPDMPrior(MotionPrior):
    """Samples every particle's next pose through the GPDM, in one batch: a model plus parts.

    Each particle carries its latent history (``order`` points) and the pending root step of its newest
    frame (see :class:`priors.conditional.ConditionalPrior` for why). A step draws the next latent point from the
    dynamics GP, mean plus ``noise_scale`` times the predictive standard deviation; the observation GP's mean gives
    the new frame's invariant features; the root moves by the pending step, plus the ``ground`` diffusion
    (:class:`~priors.parts.GroundDiffusion`). Initial latent points are the projections of the known poses. With a
    ``height`` part (:class:`~priors.parts.HeightOffset`; None, the default, is a spread of :data:`HEIGHT_SPREAD`;
    ``HeightOffset(0)`` turns it off) each particle also carries its own root-height offset, added to the heights the
    observation GP predicts, as the CRBM prior's offsets are.
    """

    name = "gpdm"
    order = 1

    def __init__(self, model: GPDMPriorModel, noise_scale: float = 1.0, *,
                 ground: GroundDiffusion = GroundDiffusion(), height: HeightOffset | None = None,
                 dtype: torch.dtype | None = None):
        import torch

        from priors.gpdm_predict import prepare

        if not noise_scale >= 0:
            raise InputError("GPDM latent noise must be non-negative")
        self.ground = ground
        height = HeightOffset(HEIGHT_SPREAD) if height is None else height
        self.height = height if height.active else None
        if self.height is not None:
            self.summary_names, self.summary_kind = (HeightOffset.SUMMARY,), "quantity"
        self.model = model
        self.predictor = prepare(model.gpdm)
        self.sampler = self.predictor.sampler(torch.float32 if dtype is None else dtype)
        self.latent_order = model.gpdm.config.order
        self.noise_scale = float(noise_scale)

    def settings(self) -> dict:
        return {"latent_noise": self.noise_scale, **self.ground.settings(),
                **(HeightOffset() if self.height is None else self.height).settings()}

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

    def start(self, known: np.ndarray, n_particles: int, rng: np.random.Generator) -> PriorState:
        known = np.atleast_2d(np.asarray(known, float))
        state = {"latent": np.repeat(self.latent_history(known[None]), n_particles, axis=0),
                 "step": np.repeat(pending_step(known)[None], n_particles, axis=0)}
        if self.height is not None:
            state.update(self.height.start(n_particles, rng))
        return state

    def adopt(self, state: PriorState, history: np.ndarray, available: int,
              rng: np.random.Generator) -> PriorState:
        """The state of particles arriving from another motion model: the latent coordinates and the step of
        their own recent poses; the height offsets those positions held."""
        real = history[:, history.shape[1] - available:]
        return {**state, "latent": self.latent_history(real), "step": pending_step(real[:, -2:])}

    def draw(self, n_particles: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Every random number of one step, drawn in one batch: standard normal ``latent`` (``P x d``),
        ``ground`` (``P x 2``) and, with a height drift, ``height`` (``P``) noise; particle ``i`` uses row ``i``."""
        noise = {"latent": rng.standard_normal((n_particles, self.model.gpdm.config.latent_dim)),
                 "ground": rng.standard_normal((n_particles, 2))}
        if self.height is not None and self.height.drift > 0:
            noise["height"] = rng.standard_normal(n_particles)
        return noise

    def advance(self, history: np.ndarray, state: PriorState, noise: dict[str, np.ndarray]
                ) -> tuple[np.ndarray, PriorState]:
        """The step of :meth:`sample` for given noise (:meth:`draw`): deterministic, and row by row the same
        for any batch of particles."""
        import torch

        step = list(STEP_FEATURES)
        x, pose_features = self.sampler.step(torch.from_numpy(np.ascontiguousarray(state["latent"])),
                                             torch.from_numpy(noise["latent"]), self.noise_scale)
        x = x.numpy()
        f_next = self.model.normaliser.inverse(pose_features.numpy())
        new = {}
        if self.height is not None:
            offset = state["height_offset"]
            new["height_offset"] = self.height.advance_with(offset, noise["height"]) if "height" in noise else offset
            shift_height(f_next, new["height_offset"])
        previous = np.zeros_like(f_next)
        previous[:, step] = state["step"]
        poses = next_poses(history[:, -1], previous, f_next)
        self.ground.apply_with(poses, noise["ground"])
        d = self.model.gpdm.config.latent_dim
        latent = np.concatenate([x, state["latent"][:, :-d]], axis=1) if self.latent_order > 1 else x
        return poses, {**new, "latent": latent, "step": f_next[:, step]}

    def sample(self, history: np.ndarray, available: int, state: PriorState,
               rng: np.random.Generator) -> tuple[np.ndarray, PriorState]:
        return self.advance(history, state, self.draw(len(state["latent"]), rng))

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray | None:
        """With height offsets, the posterior mean offset (mm); None without."""
        if self.height is None:
            return None
        return np.array([self.height.summarize(state, weights)])

    def diffusion_std(self) -> np.ndarray:
        return self.model.pose_step_rms


# ---------------------------------------------------------------------------
# Registration: building from a model file, training from clips
# ---------------------------------------------------------------------------

def train_gpdm_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                         progress: Callable[[int, int, dict], None] | None = None,
                         checkpoint: Path | None = None, resume: bool = False) -> GPDMPriorModel:
    """``train --prior gpdm``: a GPDM on the clips of ``data`` (deterministic: ``rng`` is not drawn from).

    With ``checkpoint`` (a file) and the ``checkpoint_every`` option the training state is saved there in the
    checkpoint format (never taken for a model file), atomically; ``resume`` continues from it to the model an
    uninterrupted run gives. The checkpoint is removed when training finishes."""
    from priors.gpdm_model import CHECKPOINT_FORMAT
    from priors.gpdm_training import gpdm_document, train_gpdm_prior

    config = GPDMConfig(latent_dim=options["latent_dim"], dynamics=options["dynamics"], order=options["order"],
                        balance=options["balance"], iterations=options["iterations"],
                        inducing=options.get("inducing")).check()
    every = options.get("checkpoint_every") or 0
    report = None if progress is None else (
        lambda done, value: progress(done, config.iterations, {"objective": value}))
    saved = read_training_checkpoint(checkpoint) if resume else None

    def save(model: GPDM, training_state: dict) -> None:
        torch_save_atomic({**gpdm_document(model), "format": CHECKPOINT_FORMAT, "training_state": training_state},
                          checkpoint)

    model = train_gpdm_prior(list(data.clips), config, data.fps, data.body_model.dof_names, data.body_model.name,
                             list(data.sources), report, (save, every) if checkpoint is not None and every else None,
                             saved)
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return model


def read_training_checkpoint(path: Path | None) -> GPDMCheckpoint:
    """A GPDM training checkpoint written by ``train --checkpoint-every``, checked like a model file."""
    from priors.gpdm_model import CHECKPOINT_FORMAT
    from priors.gpdm_training import GPDMCheckpoint, gpdm_from_document

    if path is None or not path.exists():
        raise InputError("no training checkpoint to resume from", path)
    doc = read_model_file(path, CHECKPOINT_FORMAT, "GPDM training checkpoint")
    state = doc.get("training_state")
    if not isinstance(state, dict):
        raise InputError("the GPDM training checkpoint lacks its training state", path)
    model, _ = gpdm_from_document(doc, path)
    return GPDMCheckpoint(model, state, path)


GPDM_TRAIN_OPTIONS = (
    Option("latent_dim", int, GPDMConfig.latent_dim, "latent dimensions (default 3)", minimum=1),
    Option("dynamics", str, GPDMConfig.dynamics, "dynamics kernel (default linear+rbf)", choices=DYNAMICS),
    Option("order", int, GPDMConfig.order, "dynamics order 1 or 2 (default 1)", choices=(1, 2)),
    Option("balance", float, GPDMConfig.balance,
           "exponent M of the prior on the observation hyperparameters (default 1)", minimum=0.0, strict=True),
    Option("iterations", int, GPDMConfig.iterations, "L-BFGS iterations (default 300)", minimum=1),
    Option("inducing", int, GPDMConfig.inducing,
           f"inducing frames of the sparse GPs, chosen by farthest-point sampling; 0 = exact (default: exact up "
           f"to {EXACT_MAX_FRAMES} training frames, {AUTO_INDUCING} above)", minimum=0),
    Option("checkpoint_every", int, None, "also save the training state every this many iterations (at the end of "
                                          "the L-BFGS chunk reaching them), for train --resume", minimum=1),
)


@register_prior(
    "gpdm", summary="Gaussian Process Dynamical Model (Wang 2005), latent coordinates carried per particle",
    model_files="one", train=train_gpdm_from_data, train_options=GPDM_TRAIN_OPTIONS, resumable=True,
    options=(Option("latent_noise", float, 1.0,
                    "multiple of the predictive standard deviation added to each latent step (default 1)",
                    minimum=0.0, maximum=MAX_LATENT_NOISE),
             *GroundDiffusion.OPTIONS,
             replace(HeightOffset.OPTIONS[0], default=HEIGHT_SPREAD),
             HeightOffset.OPTIONS[1]))
def build_gpdm(context: PriorContext, model_files: Sequence[Path], options: dict) -> GPDMPrior:
    from priors.gpdm_training import GPDMPriorModel, load_gpdm_prior

    model = loaded(model_files[0], load_gpdm_prior, GPDMPriorModel, "GPDM")
    model.check_compatible(context.body_model.name, context.body_model.dof_names, context.fps,
                           source_of(model_files[0]))
    try:
        return GPDMPrior(model, options["latent_noise"], ground=GroundDiffusion(options["root_noise"]),
                         height=HeightOffset(options["height_spread"], options["height_drift"]))
    except InputError as exc:  # a kernel matrix of the file's hyperparameters that is not positive definite
        if exc.path is not None:
            raise
        raise InputError(f"GPDM model: {exc.reason}", source_of(model_files[0])) from None
