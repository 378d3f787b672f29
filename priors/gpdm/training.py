"""Training a GPDM (Wang 2005, Ch. 4) by L-BFGS, on features or on pose clips as a motion prior's model, with
training checkpoints to resume from."""
from __future__ import annotations

import copy
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch

from priors.common import read_model_file, torch_save_atomic
from priors.gpdm.file import gpdm_from_document
from priors.gpdm.model import CHECKPOINT_FORMAT, GPDM, GPDMConfig, GPDMPriorModel, gpdm_document
from priors.gpdm.subset import Stretch, choose_frames
from priors.settings import GPDM_MAX_FRAMES
from tracker.core.errors import InputError
from tracker.core.representation import clip_features, step_rms
from tracker.engine.registry import TrainingData


@dataclass
class GPDMCheckpoint:
    """A training checkpoint read back (:func:`read_training_checkpoint`): the model as it was after
    ``state['done']`` iterations, the L-BFGS optimiser's whole state, and the file it came from."""
    model: GPDM
    state: dict
    path: Path | None = None


#: What a GPDM learns and a training checkpoint restores (with the optimiser's state and the objective history).
GPDM_PARAMETERS = ("X", "log_alpha", "log_beta", "W")


def train_gpdm(Y: np.ndarray, lengths: Sequence[int], config: GPDMConfig,
               progress: Callable[[int, float], None] | None = None,
               checkpoint: tuple[Callable[[GPDM, dict], None], int] | None = None,
               resume: GPDMCheckpoint | None = None) -> GPDM:
    """Learn a GPDM on observations ``Y`` (``N x D``, sequences concatenated) by L-BFGS.

    Training runs in chunks of ``config.w_update_every`` L-BFGS iterations, with the closed-form ``W`` update
    between chunks; one optimiser runs through all chunks, so its curvature history carries over.
    ``checkpoint = (save, every)`` calls ``save(model, training_state)`` at the end of the first chunk at or
    after every ``every`` iterations (not after the last; 0: never), and, when the training is interrupted
    (``KeyboardInterrupt``: Ctrl-C, or SIGTERM as the command line answers it) after its first chunk, with the
    model and state at the end of the last finished chunk before the interrupt goes on; the state holds the
    optimiser's ``state_dict`` (its history of steps and gradient changes, last direction and step length,
    iteration counts), so ``resume`` (such a checkpoint) restores the parameters, ``W`` and the optimiser
    exactly and continues to the model an uninterrupted run gives, bit for bit.
    """
    t0 = time.perf_counter()
    model = GPDM(Y, lengths, config)  # PCA initialisation and L-BFGS: nothing random
    model.update_W()
    opt = torch.optim.LBFGS(model.parameters(), lr=1.0, max_iter=config.w_update_every,
                            line_search_fn="strong_wolfe", history_size=20)
    done, seconds_before = 0, 0.0
    if resume is not None:
        done, seconds_before = _restore(model, opt, resume)

    def closure():
        opt.zero_grad()
        value = model.objective()
        value.backward()
        return value

    def training_state() -> dict:
        """The model's parameters, ``W``, objective history and the optimiser's state after ``done`` iterations,
        copied (later chunks leave it as it was)."""
        return {"parameters": [p.detach().clone() for p in model.parameters()], "W": model.W.clone(),
                "objective_history": list(model.objective_history), "optimizer": copy.deepcopy(opt.state_dict()),
                "done": done, "seconds": seconds_before + time.perf_counter() - t0}

    def save(state: dict) -> None:
        """``state`` (:func:`training_state`) through ``checkpoint``: the model set to it first."""
        with torch.no_grad():
            for mine, saved in zip(model.parameters(), state["parameters"]):
                mine.copy_(saved)
        model.W, model.objective_history = state["W"], list(state["objective_history"])
        model.training_seconds = state["seconds"]
        checkpoint[0](model, {k: state[k] for k in ("optimizer", "done", "seconds")})

    last = None
    try:
        while done < config.iterations:
            opt.step(closure)
            model.update_W()
            done += config.w_update_every
            with torch.no_grad():
                value = float(model.objective())
            if not math.isfinite(value):
                raise InputError("GPDM training diverged (the objective is not finite)")
            model.objective_history.append(value)
            if checkpoint is not None and done < config.iterations:
                last = training_state()
                if checkpoint[1] and done // checkpoint[1] > (done - config.w_update_every) // checkpoint[1]:
                    save(last)
            if progress is not None:
                progress(min(done, config.iterations), value)
    except KeyboardInterrupt:  # the state after the last finished chunk, for a resume to continue from
        if last is not None:
            save(last)
        raise
    model.training_seconds = seconds_before + time.perf_counter() - t0
    return model


def _restore(model: GPDM, opt: torch.optim.LBFGS, resume: GPDMCheckpoint) -> tuple[int, float]:
    """Set ``model`` and ``opt`` to the checkpoint's state; the iterations done and seconds spent before.
    A checkpoint of other data or settings is refused."""
    saved, state = resume.model, resume.state
    if (asdict(saved.config) != asdict(model.config) or saved.lengths != model.lengths
            or not torch.equal(saved.Y, model.Y)):
        raise InputError("the checkpoint is not of this training (other clips or settings)", resume.path)
    try:
        done, seconds = int(state["done"]), float(state["seconds"])
        with torch.no_grad():
            for mine, theirs in zip(model.parameters(), saved.parameters()):
                mine.copy_(theirs)
        model.W = saved.W.clone()
        model.objective_history = list(saved.objective_history)
        opt.load_state_dict(state["optimizer"])
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        raise InputError(f"the training checkpoint's optimiser state is malformed ({type(exc).__name__}: "
                         f"{str(exc)[:100]})", resume.path) from None
    if not 0 < done < model.config.iterations:
        raise InputError(f"the training checkpoint says {done} iterations were done, outside 1.."
                         f"{model.config.iterations - 1}", resume.path)
    return done, seconds


def train_gpdm_prior(clips: Sequence[np.ndarray], config: GPDMConfig, fps: float, dof_names: Sequence[str],
                     body_model: str = "15-cone", sources: Sequence[str] = (),
                     progress: Callable[[int, float], None] | None = None,
                     checkpoint: tuple[Callable[[GPDM, dict], None], int] | None = None,
                     resume: GPDMCheckpoint | None = None) -> GPDMPriorModel:
    """A GPDM on the invariant features of pose clips (each ``T x D`` at ``fps``), one sequence per clip;
    ``checkpoint`` and ``resume`` as in :func:`train_gpdm`."""
    normed, norm = clip_features(clips, dof_names)
    gpdm = train_gpdm(np.concatenate(normed), [len(f) for f in normed], config, progress, checkpoint, resume)
    return GPDMPriorModel(gpdm=gpdm, normaliser=norm, fps=fps, body_model=body_model, dof_names=list(dof_names),
                          sources=list(sources), pose_step_rms=step_rms(clips))



def train_gpdm_from_data(data: TrainingData, options: dict, rng: np.random.Generator,
                         progress: Callable[[int, int, dict], None] | None = None,
                         checkpoint: Path | None = None, resume: bool = False) -> GPDMPriorModel:
    """``train --prior gpdm``: a GPDM on the clips of ``data``, or on the stretches of them that
    :func:`priors.gpdm.subset.choose_frames` draws from ``rng`` when they hold more than ``options['max_frames']``
    frames (otherwise deterministic: ``rng`` is not drawn from).

    With ``checkpoint`` (a file) the training state is saved there every ``checkpoint_every`` iterations and when
    the training is interrupted, in the checkpoint format (never taken for a model file), atomically; ``resume``
    continues from it to the model an uninterrupted run gives. The checkpoint is removed when training finishes."""
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

    clips = list(data.clips)
    sources = list(data.sources) or [f"clip {i + 1}" for i in range(len(clips))]
    picked = choose_frames([len(c) for c in clips], sources, options.get("max_frames", GPDM_MAX_FRAMES), rng)
    if picked is not None:
        clips, sources = [clips[i][a:b] for i, a, b in picked], [sources[i] for i, _, _ in picked]
    model = train_gpdm_prior(clips, config, data.fps, data.body_model.dof_names, data.body_model.name,
                             sources if picked is not None else list(data.sources), report,
                             None if checkpoint is None else (save, every), saved)
    if picked is not None:
        model.subset = [Stretch(s, a, b) for s, (_, a, b) in zip(sources, picked)]
        model.corpus_frames = sum(len(c) for c in data.clips)
    if checkpoint is not None:
        checkpoint.unlink(missing_ok=True)
    return model


def read_training_checkpoint(path: Path | None) -> GPDMCheckpoint:
    """A GPDM training checkpoint written by ``train --checkpoint-every``, checked like a model file."""
    if path is None or not path.exists():
        raise InputError("no training checkpoint to resume from", path)
    doc = read_model_file(path, CHECKPOINT_FORMAT, "GPDM training checkpoint")
    state = doc.get("training_state")
    if not isinstance(state, dict):
        raise InputError("the GPDM training checkpoint lacks its training state", path)
    model, _ = gpdm_from_document(doc, path)
    return GPDMCheckpoint(model, state, path)
