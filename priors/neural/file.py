"""Reading a neural prior's model file: every part checked, a bad one refused in one line naming the file."""
from __future__ import annotations

import math
from pathlib import Path

import torch

from priors.common import check_weights, checked_model_data, read_model_file
from priors.neural.model import FORMAT, NeuralModel, build_net
from priors.neural.settings import NeuralConfig
from tracker.core.errors import InputError


def load_neural(path: str | Path, device: str = "cpu") -> NeuralModel:
    """A neural prior's model file, every part checked: a missing key, a weight of the wrong shape, a non-finite
    weight or normaliser, or an unknown setting is an :class:`InputError` naming the file. The weights load on
    the CPU and move to ``device``."""
    path = Path(path)
    return model_from_document(read_model_file(path, FORMAT, "neural prior"), path, device)


def model_from_document(doc: dict, path: Path | None, device: str = "cpu") -> NeuralModel:
    """The model of a model file's (or a training checkpoint's) dictionary, checked as :func:`load_neural`
    says."""
    try:
        config = doc["config"]
        if not isinstance(config, dict):
            raise InputError("neural prior model file's config is not a dictionary", path)
        unknown = sorted(set(config) - set(NeuralConfig.__dataclass_fields__))
        if unknown:
            raise InputError(f"neural prior model file has unknown settings {', '.join(map(str, unknown))}", path)
        try:
            cfg = NeuralConfig(**config).check()
        except (TypeError, ValueError) as exc:
            raise InputError(f"neural prior model file has bad settings ({exc})", path) from None
        params = doc["params"]
        if not isinstance(params, dict) or not all(isinstance(v, torch.Tensor) for v in params.values()):
            raise InputError("neural prior model file's weights are not a dictionary of tensors", path)
        if "means.bias" not in params:
            raise InputError("neural prior model file lacks the weight 'means.bias'", path)
        K, rest = divmod(params["means.bias"].numel(), cfg.components)
        if rest or K < 1:
            raise InputError(f"neural prior model file's means.bias has {params['means.bias'].numel()} numbers, "
                             f"not a multiple of its {cfg.components} components", path)
        C = int(cfg.pace_input)
        with torch.random.fork_rng(devices=[]):  # its initial weights are replaced: leave torch's global draws
            net = build_net(cfg, K, C)
        expected = {k: tuple(v.shape) for k, v in net.state_dict().items()}
        missing = sorted(set(expected) - set(params))
        extra = sorted(set(params) - set(expected))
        if missing or extra:
            raise InputError(f"neural prior model file's weights do not match its settings ("
                             f"{'lacks ' + ', '.join(missing) if missing else 'has extra ' + ', '.join(extra)})", path)
        check_weights(params, expected, "neural prior weight",
                      f"order {cfg.order}, {K} features, {cfg.layers}x{cfg.hidden} hidden, {cfg.components} "
                      "components", path)
        net.load_state_dict({k: v.to(torch.float32) for k, v in params.items()})
        net.to(device).eval()
        pace_label = _checked_pace_label(doc.get("pace_label"), cfg.pace_input, path)
        normaliser, fps, body_model, dof_names, sources, step = checked_model_data(doc, K, "neural prior", path)
        return NeuralModel(net=net, normaliser=normaliser, config=cfg, fps=fps, body_model=body_model,
                           dof_names=dof_names, sources=sources, pose_step_rms=step,
                           reconstruction_errors=[float(e) for e in doc["reconstruction_errors"]],
                           training_seconds=float(doc["training_seconds"]), pace_label=pace_label,
                           validation_errors=[[float(e), float(x)] for e, x in doc.get("validation_errors", [])],
                           best_epoch=int(doc.get("best_epoch", 0)))
    except InputError:
        raise
    except KeyError as exc:
        raise InputError(f"neural prior model file lacks {exc.args[0]!r}", path) from None
    except (TypeError, ValueError, AttributeError, RuntimeError) as exc:
        raise InputError(f"neural prior model file is malformed ({type(exc).__name__}: {str(exc)[:100]})",
                         path) from None


def _checked_pace_label(value, pace_input: bool, path: Path | None) -> tuple[float, float] | None:
    """A model file's ``pace_label`` (mean and std of the training log paces), present exactly when the model
    was trained with a pace input."""
    if not pace_input:
        if value is not None:
            raise InputError("neural prior model file has a pace_label but was not trained with a pace input", path)
        return None
    if not isinstance(value, (list, tuple)) or len(value) != 2 or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value) \
            or not value[1] > 0:
        raise InputError(f"neural prior model file's pace_label must be [mean, std > 0] of the training log paces, "
                         f"got {value!r}", path)
    return float(value[0]), float(value[1])
