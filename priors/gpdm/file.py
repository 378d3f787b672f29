"""The GPDM's model files, read and checked (:func:`~priors.gpdm.model.save_gpdm` and
:meth:`~priors.gpdm.model.GPDMPriorModel.save` write them)."""
from __future__ import annotations

import math
from pathlib import Path

import torch

from priors.common import checked_data_settings, check_weights, normaliser_from_tensors, read_model_file
from priors.gpdm.subset import Stretch
from priors.gpdm.model import FORMAT, GPDM, GPDMConfig, GPDMPriorModel, n_dynamics_params
from tracker.core.errors import InputError


def load_gpdm(path: str | Path) -> tuple[GPDM, dict]:
    """Read a model written by :func:`save_gpdm`: the GPDM and its ``extra`` metadata, every part checked
    (:func:`gpdm_from_document`). Files written before sparse models existed have no inducing frames
    (``active``) and no ``inducing`` setting: they are exact."""
    path = Path(path)
    return gpdm_from_document(read_model_file(path, FORMAT, "GPDM"), path)


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
                          sources=sources, pose_step_rms=step, subset=read_subset(extra.get("subset"), path),
                          corpus_frames=int(extra.get("corpus_frames", 0)))


def read_subset(value: object, path: Path) -> list[Stretch] | None:
    """The recorded subset of a model file's ``extra`` (None where the whole corpus was used); a malformed one is
    an :class:`InputError` naming the file."""
    if value is None:
        return None
    try:
        stretches = [Stretch(str(s["source"]), int(s["start"]), int(s["stop"])) for s in value]
    except (TypeError, KeyError, ValueError):
        raise InputError("GPDM model file's 'subset' is not a list of {source, start, stop}", path) from None
    if any(not 0 <= s.start < s.stop for s in stretches):
        raise InputError("GPDM model file's 'subset' holds an empty or negative frame range", path)
    return stretches
