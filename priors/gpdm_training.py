"""Training a GPDM (Wang 2005, Ch. 4) by L-BFGS, its model files, and a GPDM trained on pose clips as a motion
prior's model (:class:`GPDMPriorModel`)."""
from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, ClassVar, Sequence

import numpy as np
import torch

from priors.common import (
    ModelData, check_weights, checked_data_settings, normaliser_from_tensors, normaliser_to_tensors,
    read_model_file, torch_save_atomic,
)
from priors.gpdm_model import FORMAT, GPDM, GPDMConfig, n_dynamics_params
from tracker.core.errors import InputError
from tracker.core.representation import clip_features, step_rms


@dataclass
class GPDMCheckpoint:
    """A training checkpoint read back (:func:`priors.gpdm.read_training_checkpoint`): the model as it was after
    ``state['done']`` iterations, the L-BFGS optimiser's whole state, and the file it came from."""

    model: GPDM
    state: dict
    path: Path | None = None


def train_gpdm(Y: np.ndarray, lengths: Sequence[int], config: GPDMConfig,
               progress: Callable[[int, float], None] | None = None,
               checkpoint: tuple[Callable[[GPDM, dict], None], int] | None = None,
               resume: GPDMCheckpoint | None = None) -> GPDM:
    """Learn a GPDM on observations ``Y`` (``N x D``, sequences concatenated) by L-BFGS.

    Training runs in chunks of ``config.w_update_every`` L-BFGS iterations, with the closed-form ``W`` update
    between chunks; one optimiser runs through all chunks, so its curvature history carries over.
    ``checkpoint = (save, every)`` calls ``save(model, training_state)`` at the end of the first chunk at or
    after every ``every`` iterations (not after the last); the state holds the optimiser's ``state_dict`` (its
    history of steps and gradient changes, last direction and step length, iteration counts), so ``resume``
    (such a checkpoint) restores the parameters, ``W`` and the optimiser exactly and continues to the model an
    uninterrupted run gives, bit for bit.
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

    while done < config.iterations:
        opt.step(closure)
        model.update_W()
        done += config.w_update_every
        with torch.no_grad():
            value = float(model.objective())
        if not math.isfinite(value):
            raise InputError("GPDM training diverged (the objective is not finite)")
        model.objective_history.append(value)
        if progress is not None:
            progress(min(done, config.iterations), value)
        if checkpoint is not None and done < config.iterations \
                and done // checkpoint[1] > (done - config.w_update_every) // checkpoint[1]:
            model.training_seconds = seconds_before + time.perf_counter() - t0
            checkpoint[0](model, {"optimizer": opt.state_dict(), "done": done,
                                  "seconds": model.training_seconds})
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


# ---------------------------------------------------------------------------
# Model files
# ---------------------------------------------------------------------------

def gpdm_document(model: GPDM, extra: dict | None = None) -> dict:
    """The model file's dictionary (tensors and plain values; ``torch.load(weights_only=True)`` reads it)."""
    return {"format": FORMAT, "config": asdict(model.config), "lengths": list(model.lengths),
            "X": model.X.detach().clone(), "Y": model.Y.clone(), "W": model.W.clone(),
            "log_alpha": model.log_alpha.detach().clone(), "log_beta": model.log_beta.detach().clone(),
            "active": None if model.active is None else model.active.clone(),
            "objective_history": [float(v) for v in model.objective_history], "extra": extra or {}}


def save_gpdm(path: str | Path, model: GPDM, extra: dict | None = None, overwrite: bool = True) -> None:
    """Write a trained GPDM (latent points, data, scales, hyperparameters, config) and ``extra`` metadata
    (plain values or tensors) to a ``torch.save`` file loadable with ``weights_only=True``, atomically
    (:func:`priors.common.torch_save_atomic`; an existing file is refused unless ``overwrite``)."""
    torch_save_atomic(gpdm_document(model, extra), Path(path), overwrite)


def load_gpdm(path: str | Path) -> tuple[GPDM, dict]:
    """Read a model written by :func:`save_gpdm`: the GPDM and its ``extra`` metadata, every part checked
    (:func:`gpdm_from_document`). Files written before sparse models existed have no inducing frames
    (``active``) and no ``inducing`` setting: they are exact."""
    path = Path(path)
    return gpdm_from_document(read_model_file(path, FORMAT, "GPDM"), path)


#: What a GPDM learns and a training checkpoint restores (with the optimiser's state and the objective history).
GPDM_PARAMETERS = ("X", "log_alpha", "log_beta", "W")

#: Largest magnitude of a log hyperparameter (kernel scales, inverse widths, noise precisions) in a model file:
#: ``exp(+-30)`` spans 1e-13..1e13, far beyond any trained value; beyond it the kernels under- or overflow.
MAX_LOG_HYPERPARAMETER = 30.0


def gpdm_from_document(doc: dict, path: Path | None) -> tuple[GPDM, dict]:
    """The GPDM of a model file's (or training checkpoint's) dictionary and its ``extra`` metadata.

    A missing key, a setting that is unknown or of the wrong type, sequence lengths that do not add up, an
    array of the wrong type or shape, a NaN or infinite value, a non-positive scale ``W``, a log hyperparameter
    outside +-:data:`MAX_LOG_HYPERPARAMETER` (a kernel scale or noise precision of 0 or infinity) or inducing
    frames out of range is one :class:`InputError` naming the file and the key.
    """
    try:
        config = _config_from(doc["config"], path)
        lengths = doc["lengths"]
        if not isinstance(lengths, list) or not lengths \
                or any(isinstance(n, bool) or not isinstance(n, int) or n < 1 for n in lengths):
            raise InputError(f"GPDM lengths must be a list of positive frame counts, got {str(lengths)[:40]}", path)
        arrays = {key: doc[key] for key in ("Y", "X", "W", "log_alpha", "log_beta")}
        for key, t in arrays.items():
            if not isinstance(t, torch.Tensor) or not t.is_floating_point():
                raise InputError(f"GPDM {key} must be a tensor of real numbers, got {type(t).__name__}", path)
        N, D = sum(lengths), (arrays["Y"].shape[1] if arrays["Y"].ndim == 2 else -1)
        expected = {"Y": (N, D), "X": (N, config.latent_dim), "W": (D,), "log_alpha": (n_dynamics_params(config),),
                    "log_beta": (3,)}
        check_weights(arrays, expected, "GPDM", f"{N} frames (the sum of the lengths) of {D} features in "
                      f"{config.latent_dim} latent dimensions with {config.dynamics} dynamics of order {config.order}",
                      path)
        if torch.any(arrays["W"] <= 0):
            raise InputError("GPDM scales W must be positive", path)
        for key in ("log_alpha", "log_beta"):
            big = torch.nonzero(arrays[key].abs() > MAX_LOG_HYPERPARAMETER)
            if len(big):
                i = int(big[0, 0])
                raise InputError(f"GPDM {key}[{i}] = {float(arrays[key][i]):.6g}: kernel scales and noise precisions "
                                 f"are exp({key}) and must lie in exp(+-{MAX_LOG_HYPERPARAMETER:g})", path)
        active = doc.get("active")
        if active is not None and (not isinstance(active, torch.Tensor) or active.ndim != 1
                                   or active.dtype not in (torch.int32, torch.int64) or len(active) == 0
                                   or int(active.min()) < 0 or int(active.max()) >= N):
            raise InputError(f"GPDM inducing frames (active) must be a 1-D integer tensor of indices in 0..{N - 1}",
                             path)
        history = [float(v) for v in doc["objective_history"]]
        extra = doc["extra"]
        if not isinstance(extra, dict):
            raise InputError(f"GPDM extra must be a dictionary, got {type(extra).__name__}", path)
        model = GPDM(arrays["Y"].numpy(), lengths, config, X=arrays["X"].numpy(),
                     active=None if active is None else active.numpy())
    except InputError as exc:
        if exc.path is None:
            raise InputError(f"GPDM model file: {exc.reason}", path) from None
        raise
    except KeyError as exc:
        raise InputError(f"GPDM model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError) as exc:
        raise InputError(f"GPDM model file is malformed ({type(exc).__name__}: {str(exc)[:100]})", path) from None
    with torch.no_grad():
        model.log_alpha.copy_(arrays["log_alpha"])
        model.log_beta.copy_(arrays["log_beta"])
    model.W = arrays["W"].to(torch.float64).clone()
    model.objective_history = history
    return model, dict(extra)


def _config_from(settings, path: Path | None) -> GPDMConfig:
    """The :class:`GPDMConfig` of a model file, refusing unknown settings and values of the wrong type."""
    if not isinstance(settings, dict):
        raise InputError(f"GPDM config must be a dictionary, got {type(settings).__name__}", path)
    settings = dict(settings)
    settings.pop("seed", None)  # files written when the config carried an (unused) seed
    fields = GPDMConfig.__dataclass_fields__
    unknown = sorted(set(settings) - set(fields))
    if unknown:
        raise InputError(f"GPDM model file has unknown settings {', '.join(map(str, unknown))}", path)
    kinds = {"latent_dim": int, "order": int, "iterations": int, "w_update_every": int, "inducing": int,
             "balance": (int, float), "dynamics": str, "sparse_method": str}
    for key, value in settings.items():
        if key == "inducing" and value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, kinds[key]) \
                or (isinstance(value, float) and not math.isfinite(value)):
            raise InputError(f"GPDM setting {key} must be {'text' if kinds[key] is str else 'a finite number'}, "
                             f"got {str(value)[:30]!r}", path)
    return GPDMConfig(**settings).check()


# ---------------------------------------------------------------------------
# As a motion prior's model: trained on pose clips, with the data settings its file keeps
# ---------------------------------------------------------------------------

@dataclass(kw_only=True)
class GPDMPriorModel(ModelData):
    """A GPDM trained on pose clips, with the normaliser and data settings it was trained with
    (:class:`~priors.common.ModelData`)."""

    gpdm: GPDM

    KIND: ClassVar[str] = "GPDM"

    def save(self, path: str | Path, overwrite: bool = False) -> None:
        """The model file at ``path`` (atomically); an existing one is refused unless ``overwrite``."""
        save_gpdm(path, self.gpdm, overwrite=overwrite, extra={
            "fps": float(self.fps), "body_model": self.body_model, "dof_names": list(self.dof_names),
            "sources": list(self.sources), "pose_step_rms": torch.tensor(self.pose_step_rms),
            "normaliser": normaliser_to_tensors(self.normaliser),
            "training_seconds": float(self.gpdm.training_seconds)})

    def summary(self) -> str:
        """One line on how training went."""
        h, c = self.gpdm.objective_history, self.gpdm.config
        fit = f"objective {h[0]:.1f} -> {h[-1]:.1f}, " if h else ""
        g = self.gpdm
        size = (f"{len(g.Y)} frames, {len(g.active)} inducing" if g.sparse else f"{len(g.Y)} frames, exact")
        return f"{c.latent_dim}D GPDM ({c.dynamics} dynamics, order {c.order}; {size}): {fit}{g.training_seconds:.1f} s"


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


def load_gpdm_prior(path: str | Path) -> GPDMPriorModel:
    """A GPDM prior's model file: the GPDM (:func:`load_gpdm`) and its data settings, every part checked (the
    normaliser finite with positive scales and one kept feature per observed dimension; see
    :func:`priors.common.checked_data_settings`)."""
    path = Path(path)
    gpdm, extra = load_gpdm(path)
    if "normaliser" not in extra:
        raise InputError("GPDM model file lacks 'normaliser' (the data settings of a motion prior)", path)
    norm = normaliser_from_tensors(extra["normaliser"], path)
    if norm.n_kept != gpdm.Y.shape[1]:
        raise InputError(f"GPDM model has {gpdm.Y.shape[1]} observed features but its normaliser keeps "
                         f"{norm.n_kept}", path)
    fps, body_model, dof_names, sources, step = checked_data_settings(extra, "GPDM", path)
    seconds = extra.get("training_seconds", 0.0)
    gpdm.training_seconds = float(seconds) if isinstance(seconds, (int, float)) else 0.0
    return GPDMPriorModel(gpdm=gpdm, normaliser=norm, fps=fps, body_model=body_model, dof_names=dof_names,
                          sources=sources, pose_step_rms=step)
