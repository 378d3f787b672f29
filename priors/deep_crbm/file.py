"""The deep CRBM's model file: read and checked (:class:`~priors.deep_crbm.model.DeepCRBMModel` writes it)."""
from __future__ import annotations

from pathlib import Path

import torch

from priors.common import read_model_file
from priors.crbm.file import model_from_document
from priors.crbm.model import CRBM
from priors.deep_crbm.model import FORMAT, DeepCRBMModel
from priors.settings import TopConfig
from tracker.core.errors import InputError


def load_deep_crbm(path: str | Path, device: str = "cpu") -> DeepCRBMModel:
    """A deep CRBM model file, every part checked (the first layer as a CRBM model file is); a damaged file is an
    :class:`InputError` naming it."""
    path = Path(path)
    doc = read_model_file(path, FORMAT, "deep CRBM")
    try:
        bottom = model_from_document(doc["bottom"], path, device)
        if bottom.pace_label is not None:
            raise InputError("deep CRBM's first layer has a pace input, which the deep prior does not use", path)
        unknown = sorted(set(doc["top_config"]) - set(TopConfig.__dataclass_fields__))
        if unknown:
            raise InputError(f"deep CRBM model file has unknown settings {', '.join(unknown)}", path)
        cfg = TopConfig(**doc["top_config"]).check()
        params, H1, N = doc["top"], bottom.crbm.n_hidden, cfg.order
        if not isinstance(params.get("W"), torch.Tensor) or params["W"].ndim != 2:
            raise InputError("deep CRBM second-layer weight W must be a 2-D tensor", path)
        H2 = params["W"].shape[1]
        expected = {"W": (H1, H2), "A": (N * H1, H1), "B": (N * H1, H2), "a": (H1,), "b": (H2,)}
        for k, shape in expected.items():
            if not isinstance(params.get(k), torch.Tensor) or tuple(params[k].shape) != shape:
                raise InputError(f"deep CRBM second-layer weight {k} must have shape {shape} (order {N} on "
                                 f"{H1} first-layer hidden units)", path)
            if not torch.all(torch.isfinite(params[k])):
                raise InputError(f"deep CRBM second-layer weight {k} contains NaN or infinite values", path)
        top = CRBM(H1, H2, N, device=device)
        top.load_state_dict(params)
        return DeepCRBMModel(bottom, top, cfg, [float(e) for e in doc["reconstruction_errors"]],
                             float(doc["training_seconds"]))
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"deep CRBM model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError, IndexError) as exc:
        raise InputError(f"deep CRBM model file is malformed ({type(exc).__name__}: {str(exc)[:100]})",
                         path) from None
