"""Checkpoints of a tracking run: the filter's whole state, the generator's state and what was recorded so far,
in one ``.npz`` written atomically, so an interrupted run resumes to the result an uninterrupted one gives.

The file also holds a fingerprint of the run's settings; resuming with other settings is refused.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from data_tools.checks import load_npz
from data_tools.files import atomic_path
from tracker.core.errors import InputError
from tracker.engine.filter import FilterState
from tracker.engine.recording import STAGES, Recording
from tracker.engine.weights import LogWeights

FORMAT = "pose-tracker checkpoint v1"


def save_checkpoint(path: str | Path, state: FilterState, recording: Recording, rng_state: dict,
                    fingerprint: dict, extra: dict | None = None) -> None:
    """Write the checkpoint (atomically: a crash while writing leaves the previous one). ``rng_state`` is the
    generator's ``bit_generator.state`` taken together with ``state``, so that resuming redraws nothing."""
    arrays: dict[str, np.ndarray] = {
        "history": state.history, "log_weights": state.weights.log_w, "recent_estimates": state.recent_estimates,
    }
    ps = state.prior_state
    kind = "none" if ps is None else ("dict" if isinstance(ps, dict) else "array")
    prior_arrays, nones = _flat_state(ps, "prior_state")
    arrays.update(prior_arrays)
    for name, values in recording.values.items():
        arrays[f"record.{name}"] = np.array(values)
    meta = {"format": FORMAT, "available": state.available, "tracked": state.tracked, "prior_state": kind,
            "prior_state_none": nones, "records": list(recording.values), "rng": rng_state,
            "fingerprint": fingerprint, "extra": extra or {}}
    arrays["meta"] = np.array(json.dumps(meta, default=_jsonable))
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)


def _flat_state(state: Any, name: str) -> tuple[dict[str, np.ndarray], list[str]]:
    """A prior's per-particle state as named arrays: an array under ``name``, a dict's entries under
    ``name.key``, nested dicts (an ensemble's members' states) one level further each; also the names of its
    None entries, which have no array."""
    if state is None:
        return {}, [name]
    if not isinstance(state, dict):
        return {name: np.asarray(state)}, []
    arrays: dict[str, np.ndarray] = {}
    nones: list[str] = []
    for key, value in state.items():
        a, n = _flat_state(value, f"{name}.{key}")
        arrays.update(a)
        nones += n
    return arrays, nones


def _nested_state(arrays: dict, nones: list[str], name: str) -> dict:
    """The dict state that :func:`_flat_state` wrote under ``name``."""
    out: dict = {}
    for path in [k for k in arrays if k.startswith(name + ".")] + [k for k in nones if k.startswith(name + ".")]:
        *parents, leaf = path[len(name) + 1:].split(".")
        node = out
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = arrays.get(path)
    return out


def _jsonable(x: Any) -> Any:
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def load_checkpoint(path: str | Path, fingerprint: dict, recording: Recording,
                    rng: np.random.Generator) -> tuple[FilterState, dict]:
    """Restore a checkpoint into ``recording`` and ``rng``; returns the filter state and the saved ``extra``.
    A checkpoint of other settings (``fingerprint``) or a damaged file is an :class:`InputError`."""
    arrays = load_npz(path, "checkpoint", ("meta", "history", "log_weights", "recent_estimates"))
    try:
        meta = json.loads(str(arrays["meta"]))
    except (json.JSONDecodeError, TypeError):
        raise InputError("checkpoint's meta data is not JSON", path) from None
    if meta.get("format") != FORMAT:
        raise InputError(f"not a checkpoint of this version (expected {FORMAT!r})", path)
    saved = json.loads(json.dumps(meta["fingerprint"]))
    if saved != json.loads(json.dumps(fingerprint, default=_jsonable)):
        changed = sorted(k for k in set(saved) | set(fingerprint) if saved.get(k) != json.loads(
            json.dumps(fingerprint.get(k), default=_jsonable)))
        raise InputError(f"the checkpoint was written with other settings ({', '.join(changed)}); resume with "
                         "the same ones or start again", path)
    kind = meta["prior_state"]
    if kind == "none":
        prior_state = None
    elif kind == "array":
        prior_state = arrays["prior_state"]
    else:
        prior_state = _nested_state(arrays, meta.get("prior_state_none", []), "prior_state")
    stages = [f"record.{k}_seconds" for k in STAGES]
    if "record.wall_seconds" not in arrays and all(k in arrays for k in stages):
        # written before frames recorded their wall time, when a frame's stages did not overlap
        arrays["record.wall_seconds"] = sum(arrays[k] for k in stages)
    missing = [n for n in recording.values if f"record.{n}" not in arrays]
    if missing:
        raise InputError(f"checkpoint lacks the recorded {', '.join(missing)}", path)
    for name in recording.values:
        recording.values[name] = list(arrays[f"record.{name}"])
    rng.bit_generator.state = meta["rng"]
    state = FilterState(arrays["history"], prior_state, LogWeights(arrays["log_weights"]),
                        arrays["recent_estimates"], int(meta["available"]), int(meta["tracked"]))
    return state, meta.get("extra", {})
