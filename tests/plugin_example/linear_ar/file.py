"""Reading a linear autoregressive model file, every part checked (a bad one is an InputError naming it)."""
from pathlib import Path

from priors.common import check_weights, checked_model_data, read_model_file
from tracker.core.errors import InputError

from .model import FORMAT, LinearARModel


def load_linear_ar(path: str | Path, device: str = "cpu") -> LinearARModel:
    """The model of ``path`` (``device`` is where a torch model would go; this one is numpy arrays)."""
    doc = read_model_file(path, FORMAT, LinearARModel.KIND)
    try:
        K = doc["b"].shape[0]
        check_weights(doc, {"A": (K, K), "b": (K,), "noise": (K,)}, "linear autoregressive", f"{K} features", path)
        normaliser, fps, body_model, dof_names, sources, step = checked_model_data(doc, K, LinearARModel.KIND, path)
        return LinearARModel(A=doc["A"].numpy(), b=doc["b"].numpy(), noise=doc["noise"].numpy(), normaliser=normaliser,
                             fps=fps, body_model=body_model, dof_names=dof_names, sources=sources, pose_step_rms=step)
    except (KeyError, AttributeError, TypeError) as exc:
        raise InputError(f"linear autoregressive model file is malformed ({exc})", path) from None
