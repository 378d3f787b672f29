"""A cache of retargeted clips keyed by content, so that a corpus is retargeted once.

Retargeting (:func:`~data_tools.motion.retarget.retarget`) fits every frame and takes seconds per clip; the same files
are converted again by every ``train``, ``compare`` and script that reads them. The cache keeps each result in
one ``.npz`` file named by a SHA-256 key of everything that determines its numbers:

- the mocap file's bytes and its separate skeleton's bytes (an AMC's ASF), if any;
- the joint map (its parsed content, not its file name), the length unit and the source rate given;
- the frame rate the clip is resampled to;
- the retarget version: a digest of the source of the converting code (the readers, retargeting and the
  geometry they use, :data:`CONVERSION_MODULES`, and the module of a plugin's reader), so that any change to
  how files are converted makes new entries.

Where it lives (:func:`cache_folder`): ``$POSE_TRACKER_CACHE`` when set (``off`` turns the cache off), else the
platform's user cache folder (``$XDG_CACHE_HOME/pose-tracker``, ``~/.cache/pose-tracker``;
``~/Library/Caches/pose-tracker`` on macOS; ``%LOCALAPPDATA%\\pose-tracker\\Cache`` on Windows), under
``clips/``. Entries are written atomically (a temporary file renamed into place), so a reader never sees half
an entry; an entry that cannot be read back (truncated, corrupt, another layout) is recomputed and replaced.
Deleting the folder is always safe.
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import sys
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from data_tools.io.files import atomic_path
from data_tools.io.fingerprints import file_hash

log = logging.getLogger(__name__)

#: The layout of an entry; part of every key.
CACHE_LAYOUT = "pose-tracker retargeted clip v1"
#: The environment variable naming the cache folder (``off``: no cache).
CACHE_ENV = "POSE_TRACKER_CACHE"

_code_digest: dict[str, str] = {}


def cache_folder() -> Path | None:
    """The user's cache folder for pose-tracker (see the module docstring); None when ``$POSE_TRACKER_CACHE`` is
    ``off`` (or ``0``, ``none``, ``no``)."""
    given = os.environ.get(CACHE_ENV)
    if given is not None and given.strip():
        if given.strip().lower() in ("off", "0", "none", "no", "false"):
            return None
        return Path(given).expanduser()
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA")
        return Path(base or Path.home() / "AppData" / "Local") / "pose-tracker" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "pose-tracker"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "pose-tracker"


#: The modules whose code determines a converted clip's numbers: the built-in readers, retargeting and the
#: geometry they use (a test checks that reading and retargeting import no other module of the package).
CONVERSION_MODULES = (
    "data_tools.motion.asf_amc", "data_tools.motion.bvh", "data_tools.io.checks", "data_tools.motion.joint_names",
    "data_tools.motion.load", "data_tools.motion.mocap", "data_tools.motion.readers", "data_tools.motion.retarget",
    "data_tools.motion.skeleton_points", "data_tools.io.textfiles", "tracker.core.arrays", "tracker.core.body", "tracker.core.errors",
    "tracker.core.kinematics", "tracker.core.rotations", "tracker.core.timewarp",
)


def _source_files(modules: tuple[str, ...]) -> list[Path]:
    import importlib

    files = []
    for name in modules:
        module = sys.modules.get(name) or importlib.import_module(name)
        path = getattr(module, "__file__", None)
        if path:
            files.append(Path(path))
    return files


def retarget_version(reader_module: str | None = None) -> str:
    """The version of the conversion: a digest of the converting code's source (:data:`CONVERSION_MODULES`, and
    ``reader_module``, a plugin reader's), hex. A release that changes how files convert changes that source,
    so its entries are new ones."""
    key = reader_module or ""
    if key not in _code_digest:
        h = hashlib.sha256(f"{CACHE_LAYOUT}\n".encode())
        modules = CONVERSION_MODULES + ((reader_module,) if reader_module not in (None, *CONVERSION_MODULES) else ())
        for path in _source_files(modules):
            try:
                h.update(path.name.encode() + b"\0" + path.read_bytes())
            except OSError:  # a module without readable source: its name at least
                h.update(path.name.encode())
        _code_digest[key] = h.hexdigest()
    return _code_digest[key]


def _joint_map_content(joint_map: str | Path | Mapping | None):
    if joint_map is None:
        return None
    if isinstance(joint_map, Mapping):
        return {str(k): str(v) for k, v in joint_map.items()}
    return {"file": file_hash(Path(joint_map))}


def clip_key(path: str | Path, skeleton: str | Path | None = None, joint_map: str | Path | Mapping | None = None,
             mm_per_unit: float | None = None, source_fps: float | None = None, fps: float | None = None,
             reader_module: str | None = None) -> str:
    """The cache key (hex SHA-256) of ``path`` retargeted at ``fps`` Hz (None: its own rate) with these reading
    options: see the module docstring for what it covers."""
    ident = {"layout": CACHE_LAYOUT, "file": file_hash(Path(path)),
             "skeleton": None if skeleton is None else file_hash(Path(skeleton)),
             "joint_map": _joint_map_content(joint_map), "mm_per_unit": mm_per_unit,
             "source_fps": None if source_fps is None else float(source_fps),
             "fps": None if fps is None else float(fps), "version": retarget_version(reader_module)}
    return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()


def entry_path(folder: Path, key: str) -> Path:
    """Where the entry ``key`` lives under the cache ``folder``."""
    return Path(folder) / "clips" / key[:2] / f"{key}.npz"


def _save(path: Path, result) -> None:
    shape = json.dumps(result.model.shape.to_dict())
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, poses=result.poses, markers=result.markers, model_markers=result.model_markers,
                     fps=np.float64(result.fps), source=np.str_(result.source), shape=np.str_(shape),
                     layout=np.str_(CACHE_LAYOUT))


def _load(path: Path, source: str):
    """The entry at ``path`` as a :class:`~data_tools.motion.retarget.RetargetResult` (its ``source`` the path the
    caller read, which may differ from the one it was cached under), or None when it cannot be read."""
    from data_tools.motion.retarget import RetargetResult
    from tracker.core.body import BodyShape, fifteen_cone_model

    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["layout"]) != CACHE_LAYOUT:
                return None
            poses, markers, model_markers = z["poses"], z["markers"], z["model_markers"]
            fps = float(z["fps"])
            shape = BodyShape.from_dict(json.loads(str(z["shape"])), str(path))
        if (poses.ndim != 2 or markers.shape != model_markers.shape or markers.ndim != 3
                or len(markers) != len(poses) or not np.isfinite(poses).all()):
            return None
        return RetargetResult(fifteen_cone_model(shape), poses, markers, model_markers, fps, source)
    except Exception as exc:  # any damage (truncated zip, bad JSON, missing arrays): recompute
        log.debug(f"cache entry {path} unreadable ({type(exc).__name__}: {exc}); converting again")
        return None


def cached_retarget(convert: Callable[[], object], path: str | Path, *, skeleton: str | Path | None = None,
                    joint_map: str | Path | Mapping | None = None, mm_per_unit: float | None = None,
                    source_fps: float | None = None, fps: float | None = None, reader_module: str | None = None,
                    folder: Path | None | bool = True):
    """The retargeted clip of ``path`` from the cache, else ``convert()``'s result, stored for the next time.

    ``folder``: the cache folder; True: :func:`cache_folder`; None or False: no cache (``convert()`` only).
    A cache that cannot be written (read-only, full) is skipped with a debug log line: the clip is still
    returned."""
    folder = cache_folder() if folder is True else (folder or None)
    if folder is None:
        return convert()
    key = clip_key(path, skeleton, joint_map, mm_per_unit, source_fps, fps, reader_module)
    entry = entry_path(Path(folder), key)
    if entry.is_file():
        hit = _load(entry, str(path))
        if hit is not None:
            return hit
    result = convert()
    try:
        _save(entry, result)
    except Exception as exc:  # the cache is an optimisation: a failure to write it never fails the work
        log.debug(f"could not write cache entry {entry}: {exc}")
    return result
