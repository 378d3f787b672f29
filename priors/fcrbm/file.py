"""The FCRBM's model file: read and checked (:class:`~priors.fcrbm.model.FCRBMModel` writes it)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import torch

from priors.common import check_weights, checked_model_data, read_model_file
from priors.fcrbm.model import FCRBM, FORMAT, LABEL_PATTERN, FCRBMModel
from priors.settings import FCRBMConfig
from tracker.core.errors import InputError


def load_fcrbm(path: str | Path, device: str = "cpu") -> FCRBMModel:
    """An FCRBM model file (with the lower-order models it grows from), every part checked: a missing key, a
    weight of the wrong shape, a non-finite weight or normaliser, a bad label set or an unknown setting is an
    :class:`InputError` naming the file."""
    path = Path(path)
    return _from_document(read_model_file(path, FORMAT, "FCRBM"), path, device)


def model_from_document(doc: dict, path: Path, device: str = "cpu") -> FCRBMModel:
    """An FCRBM model (with its growth models) from a model file's or training checkpoint's dictionary, checked as
    :func:`load_fcrbm` checks a file."""
    return _from_document(doc, path, device)


def _check_labels(labels: Any, path: Path) -> list[str]:
    if not isinstance(labels, list) or not labels or not all(isinstance(t, str) for t in labels):
        raise InputError("FCRBM model file's labels must be a non-empty list of strings", path)
    if len(set(labels)) != len(labels) or not all(LABEL_PATTERN.match(t) for t in labels):
        raise InputError(f"FCRBM model file's labels {labels} are repeated or malformed", path)
    return labels


def _from_document(doc: dict, path: Path, device: str) -> FCRBMModel:
    try:
        unknown = sorted(set(doc["config"]) - set(FCRBMConfig.__dataclass_fields__))
        if unknown:
            raise InputError(f"FCRBM model file has unknown settings {', '.join(unknown)}", path)
        try:
            cfg = FCRBMConfig(**doc["config"]).check()
        except (TypeError, ValueError, InputError) as exc:
            raise InputError(f"FCRBM model file has bad settings ({getattr(exc, 'reason', exc)})", path) from None
        labels = _check_labels(doc["labels"], path)
        clip_labels = [str(t) for t in doc["clip_labels"]]
        if set(clip_labels) - set(labels) or len(clip_labels) != len(doc["sources"]):
            raise InputError("FCRBM model file's clip labels do not match its labels and sources", path)
        params = doc["params"]
        if not isinstance(params, dict) or any(not isinstance(params.get(k), torch.Tensor) for k in FCRBM.PARAMS):
            raise InputError(f"FCRBM model file lacks weights {', '.join(FCRBM.PARAMS)}", path)
        for k in ("Wv", "Wh", "Z"):
            if params[k].ndim != 2:
                raise InputError(f"FCRBM weight {k} must be 2-D, got shape {tuple(params[k].shape)}", path)
        K, H, F, L = params["Wv"].shape[0], params["Wh"].shape[0], params["Wv"].shape[1], params["Z"].shape[0]
        net = FCRBM(K, H, cfg.order, len(labels), L, F, device=device)
        check_weights(params, net.shapes(), "FCRBM weight", f"order {cfg.order} with {K} visible, {H} hidden units, "
                      f"{F} factors, {L} features and {len(labels)} labels", path)
        net.load_state_dict(params)
        normaliser, fps, body_model, dof_names, sources, step = checked_model_data(doc, K, "FCRBM", path)
        growth = [_from_document(g, path, device) for g in doc.get("growth", [])]
        if any(g.labels != labels for g in growth):
            raise InputError("FCRBM model file's growth models have other labels", path)
        return FCRBMModel(fcrbm=net, labels=labels, normaliser=normaliser, config=cfg, fps=fps, body_model=body_model,
                          dof_names=dof_names, sources=sources, clip_labels=clip_labels, pose_step_rms=step,
                          reconstruction_errors=[float(e) for e in doc["reconstruction_errors"]],
                          training_seconds=float(doc["training_seconds"]), growth=growth)
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"FCRBM model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError, IndexError) as exc:
        raise InputError(f"FCRBM model file is malformed ({type(exc).__name__}: {str(exc)[:100]})", path) from None
