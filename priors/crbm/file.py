"""Reading a CRBM model file: every part checked, a bad one refused in one line naming the file."""
from __future__ import annotations

import math
from pathlib import Path

import torch

from priors.common import check_weights, checked_model_data, read_model_file
from priors.crbm.model import CRBM, FORMAT, INPUT_SETTINGS, CRBMConfig, CRBMModel
from tracker.core.errors import InputError

def load_crbm(path: str | Path, device: str = "cpu") -> CRBMModel:
    """A CRBM model file (with the lower-order models it grows from), every part checked: a missing key, a
    weight of the wrong shape, a non-finite weight or normaliser, or an unknown setting is an InputError
    naming the file."""
    path = Path(path)
    return model_from_document(read_model_file(path, FORMAT, "CRBM"), path, device)


def model_from_document(doc: dict, path: Path, device: str) -> CRBMModel:
    try:
        config = dict(doc["config"])
        config.pop("seed", None)  # files written before the generator came from the caller
        # Settings of earlier versions: heights learned above the subject's standing height (refused: the
        # tracker predicts heights above the floor) and a training augmentation (nothing in sampling).
        if config.pop("standing_height", False):
            raise InputError("CRBM model file learned root heights above standing, which this version does not "
                             "track; retrain it with this version", path)
        config.pop("posture_offset", None)
        unknown = sorted(set(config) - set(CRBMConfig.__dataclass_fields__))
        if unknown:
            raise InputError(f"CRBM model file has unknown settings {', '.join(unknown)}", path)
        try:
            cfg = CRBMConfig(**config).check()
        except (TypeError, ValueError) as exc:
            raise InputError(f"CRBM model file has bad settings ({exc})", path) from None
        params = doc["params"]
        if not isinstance(params, dict) or any(not isinstance(params.get(k), torch.Tensor) for k in CRBM.PARAMS):
            raise InputError(f"CRBM model file lacks weights {', '.join(CRBM.PARAMS)}", path)
        if params["W"].ndim != 2:
            raise InputError(f"CRBM weight W must be 2-D, got shape {tuple(params['W'].shape)}", path)
        K, H = params["W"].shape
        N = cfg.order
        pace_label = _checked_pace_label(doc.get("pace_label"), cfg.pace_input, path)
        C = int(cfg.pace_input)
        expected = {"W": (K, H), "A": (C + N * K, K), "B": (C + N * K, H), "a": (K,), "b": (H,)}
        check_weights(params, expected, "CRBM weight", f"order {N} with {K} visible and {H} hidden units"
                      f"{' and a pace input' if C else ''}", path)
        crbm = CRBM(K, H, N, device=device, n_context=C)
        crbm.load_state_dict(params)
        normaliser, fps, body_model, dof_names, sources, step = checked_model_data(doc, K, "CRBM", path)
        growth = [model_from_document(g, path, device) for g in doc.get("growth", [])]
        for key, what in INPUT_SETTINGS.items():
            if any(getattr(g.config, key) != getattr(cfg, key) for g in growth):
                raise InputError(f"CRBM model file's growth models and main model differ in {what}", path)
        return CRBMModel(crbm=crbm, normaliser=normaliser, config=cfg, fps=fps, body_model=body_model,
                         dof_names=dof_names, sources=sources, pose_step_rms=step,
                         reconstruction_errors=[float(e) for e in doc["reconstruction_errors"]],
                         training_seconds=float(doc["training_seconds"]), growth=growth, pace_label=pace_label,
                         validation_errors=[[float(e), float(x)] for e, x in doc.get("validation_errors", [])],
                         best_epoch=int(doc.get("best_epoch", 0)))
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"CRBM model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError) as exc:
        raise InputError(f"CRBM model file is malformed ({type(exc).__name__}: {str(exc)[:100]})", path) from None


def _checked_pace_label(value, pace_input: bool, path: Path) -> tuple[float, float] | None:
    """A model file's ``pace_label`` (mean and std of the training log paces), present exactly when the model
    was trained with a pace input; anything else is an InputError naming the file."""
    if not pace_input:
        if value is not None:
            raise InputError("CRBM model file has a pace_label but was not trained with a pace input", path)
        return None
    if not isinstance(value, (list, tuple)) or len(value) != 2 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value) \
            or not value[1] > 0:
        raise InputError(f"CRBM model file's pace_label must be [mean, std > 0] of the training log paces, "
                         f"got {value!r}", path)
    return float(value[0]), float(value[1])

