"""Checkpoints of a tracking run: the filter's whole state, the generator's state and what was recorded so far,
in one ``.npz`` written atomically, so an interrupted run resumes to the result an uninterrupted one gives.

The file also holds a fingerprint of the run's settings and of its inputs (the content hash of every file of
the sequence and of every model file, and the package version: :mod:`data_tools.io.fingerprints`); resuming with
other settings, or after an input changed, is refused with one line naming what changed.
"""
from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterable, Iterator

import numpy as np

from data_tools.io.checks import load_npz
from data_tools.io.files import atomic_path, write_text_atomic, writing
from tracker.core.errors import InputError
from tracker.engine.filter import FilterState
from tracker.engine.recording import STAGES, Recording
from tracker.engine.weights import LogWeights

FORMAT = "pose-tracker checkpoint v1"


def save_checkpoint(path: str | Path, state: FilterState, recording: Recording, rng_state: dict,
                    fingerprint: dict, extra: dict | None = None, inputs: dict | None = None) -> None:
    """Write the checkpoint (atomically: a crash or a full disk while writing leaves the previous one, and a
    failed write is one line naming the file and the cause). ``rng_state`` is the generator's
    ``bit_generator.state`` taken together with ``state``, so that resuming redraws nothing; ``inputs`` is
    :func:`input_fingerprint` of the run."""
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
            "fingerprint": fingerprint, "extra": extra or {}, "inputs": inputs}
    arrays["meta"] = np.array(json.dumps(meta, default=_jsonable))
    kept = "the previous checkpoint is kept" if Path(path).exists() else ""
    with atomic_path(path, kept) as tmp:
        np.savez(tmp, **arrays)


def input_fingerprint(sequence: str | Path, models: Iterable[str | Path], cache: Path | None = None) -> dict:
    """What a run read, by content: each file of the ``sequence`` folder, each model file (files that do not
    exist, e.g. models given in memory, are left out), and the package version. ``cache`` keeps the file
    hashes for the next run (:func:`data_tools.io.fingerprints.cached_file_hashes`)."""
    import tracker
    from data_tools.io.fingerprints import model_fingerprint, sequence_fingerprint

    return {"sequence": sequence_fingerprint(sequence, cache),
            "models": model_fingerprint([m for m in models if Path(m).is_file()], cache),
            "version": tracker.__version__}


def check_inputs(saved: dict | None, now: dict | None, path: str | Path) -> None:
    """Refuse to resume from the checkpoint ``path`` when an input in its fingerprint ``saved`` differs from
    ``now`` (:func:`input_fingerprint`): one line naming the changed files, model files or version. A
    checkpoint written without a fingerprint of its inputs is not checked."""
    from data_tools.io.fingerprints import changed_files

    if not saved or now is None:
        return
    why = []
    files = changed_files(saved.get("sequence", {}), now.get("sequence", {}))
    if files:
        shown = ", ".join(files[:3]) + (", ..." if len(files) > 3 else "")
        why.append(f"{len(files)} of the sequence's {len(now.get('sequence', {}))} files changed ({shown})")
    for model in changed_files(saved.get("models", {}), now.get("models", {})):
        why.append(f"the model file {model} changed")
    _refuse_resume(why, saved.get("version"), now.get("version"), "run", path)


def _refuse_resume(why: list[str], version_then: str | None, version_now: str | None, what: str, path) -> None:
    """Refuse to resume ``what`` (the run, the training) from the checkpoint at ``path`` when its inputs changed
    (``why``: what changed) or the package's version did."""
    if version_then != version_now:
        why = [*why, f"pose-tracker changed from version {version_then} to {version_now}"]
    if why:
        raise InputError(f"cannot resume: since the checkpoint was written, {'; '.join(why)}; start the {what} "
                         "again", path)


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
                    rng: np.random.Generator, inputs: dict | None = None) -> tuple[FilterState, dict]:
    """Restore a checkpoint into ``recording`` and ``rng``; returns the filter state and the saved ``extra``.
    A checkpoint of other settings (``fingerprint``), of inputs that changed since (``inputs``,
    :func:`check_inputs`) or a damaged file is an :class:`InputError`."""
    arrays = load_npz(path, "checkpoint", ("meta", "history", "log_weights", "recent_estimates"))
    try:
        meta = json.loads(str(arrays["meta"]))
    except (json.JSONDecodeError, TypeError):
        raise InputError("checkpoint's meta data is not JSON", path) from None
    if meta.get("format") != FORMAT:
        raise InputError(f"not a checkpoint of this version (expected {FORMAT!r})", path)
    check_inputs(meta.get("inputs"), inputs, path)
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


def _training_files(sources: Iterable[str], skeletons: Iterable[str | Path] | None) -> list[Path]:
    """The files a training reads: its clips and their skeletons (given, or the ASF found beside each AMC)."""
    from data_tools.motion.load import find_skeleton

    clips = [Path(s) for s in sources if Path(s).is_file()]
    given = [Path(s) for s in skeletons or []]
    found = [] if given else [find_skeleton(c) for c in clips if c.suffix.lower() == ".amc"]
    return list(dict.fromkeys(clips + given + found))


@contextmanager
def training_checkpoint(checkpoint: str | Path | None, sources: Iterable[str],
                        skeletons: Iterable[str | Path] | None, resume: bool, saving: bool) -> Iterator[None]:
    """The block that trains with a checkpoint file: the content hashes of the training files and the package
    version are kept beside it (``CHECKPOINT.inputs.json``) while a checkpoint may be written (``saving``), and a
    resume refuses, in one line, inputs that changed since; a checkpoint that cannot be written (no space,
    read-only, no permission) is one line too, and the previous one is kept. The hashes are removed when the
    training finishes."""
    import tracker
    from data_tools.io.fingerprints import changed_files, model_fingerprint

    if checkpoint is None or not (saving or resume):
        yield
        return
    checkpoint = Path(checkpoint)
    side = checkpoint.with_name(checkpoint.name + ".inputs.json")
    now = {"files": model_fingerprint(_training_files(sources, skeletons)), "version": tracker.__version__}
    if resume and side.is_file() and checkpoint.is_file():
        try:
            saved = json.loads(side.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            saved = None
        if isinstance(saved, dict):
            why = [f"the training file {f} changed" for f in changed_files(saved.get("files", {}), now["files"])]
            _refuse_resume(why, saved.get("version"), now["version"], "training", checkpoint)
    elif not resume:
        write_text_atomic(side, json.dumps(now, indent=1))
    with writing(checkpoint, "any earlier checkpoint is kept"):
        yield
    side.unlink(missing_ok=True)
