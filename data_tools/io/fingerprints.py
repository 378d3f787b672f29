"""Content fingerprints of a run's inputs (the sequence's files, model files, the package version), so that a
resumed run refuses inputs that changed since it was interrupted and ``compare`` recognises its finished runs.

A sequence is hashed file by file (SHA-256 of the bytes, :func:`file_hash`). Hashing
hundreds of images takes a moment, so each file's hash is cached by its size and modification time in a small
JSON file in the *output* folder (:data:`CACHE_NAME`): inputs are never written to (a sequence folder may be
read-only or shared), and the output folder is where the next run that needs the hashes -- a resume, a rerun
of ``compare`` -- looks. A file whose size or modification time changed is hashed again; a cache that is
missing, unreadable or of another layout is rebuilt.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any, Iterable

from data_tools.io.files import write_text_atomic
from tracker.core.errors import InputError

#: The cache of file hashes, in the output folder.
CACHE_NAME = ".fingerprints.json"
CACHE_FORMAT = "pose-tracker file hashes v1"


def file_hash(path: Path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def config_hash(obj: Any, length: int = 16) -> str:
    """A short stable hash of a JSON-able object (keys sorted)."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:length]


def _load_cache(path: Path | None) -> dict:
    if path is None or not path.is_file():
        return {}
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return doc.get("files", {}) if isinstance(doc, dict) and doc.get("format") == CACHE_FORMAT else {}


def cached_file_hashes(files: Iterable[Path], cache: Path | None = None) -> dict[str, str]:
    """SHA-256 (hex) of each file's bytes by its absolute path, reusing ``cache`` (a JSON file) for files whose
    size and modification time (ns) are unchanged, and updating it. A cache that cannot be written is skipped:
    the hashes are right either way, only the next run pays for them again."""
    known = _load_cache(cache)
    hashes: dict[str, str] = {}
    entries: dict[str, list] = {}
    fresh = False
    for f in files:
        key = str(Path(f).resolve())
        try:
            st = os.stat(key)
        except OSError as exc:
            raise InputError(f"cannot read ({exc.strerror})", f) from None
        entry = known.get(key)
        if isinstance(entry, list) and len(entry) == 3 and entry[:2] == [st.st_size, st.st_mtime_ns]:
            digest = entry[2]
        else:
            try:
                digest = file_hash(Path(key))
            except OSError as exc:
                raise InputError(f"cannot read ({exc.strerror})", f) from None
            fresh = True
        hashes[key] = digest
        entries[key] = [st.st_size, st.st_mtime_ns, digest]
    if cache is not None and (fresh or set(entries) - set(known)):
        try:
            write_text_atomic(cache, json.dumps({"format": CACHE_FORMAT, "files": {**known, **entries}}))
        except InputError:
            pass
    return hashes


def sequence_files(root: Path) -> list[Path]:
    """Every file of a sequence folder (images, cameras, ground truth, ...), in a fixed order."""
    return sorted(p for p in Path(root).rglob("*") if p.is_file())


def sequence_fingerprint(root: str | Path, cache: Path | None = None) -> dict[str, str]:
    """Content hash (16 hex digits) of each file of the sequence folder ``root``, by its path relative to
    ``root``."""
    root = Path(root).resolve()
    files = sequence_files(root)
    hashes = cached_file_hashes(files, cache)
    return {str(f.relative_to(root)): hashes[str(f)][:16] for f in files}


def sequence_hash(root: str | Path, cache: Path | None = None) -> str:
    """One content hash of a whole sequence folder (its files' names and bytes)."""
    return config_hash(sorted(sequence_fingerprint(root, cache).items()))


def model_fingerprint(models: Iterable[str | Path], cache: Path | None = None) -> dict[str, str]:
    """Content hash (16 hex digits) of each model file, by its path."""
    files = [Path(m) for m in models]
    hashes = cached_file_hashes(files, cache)
    return {str(f): hashes[str(f.resolve())][:16] for f in files}


def changed_files(saved: dict[str, str], now: dict[str, str]) -> list[str]:
    """Names in either fingerprint whose hash differs (added, removed or changed files), sorted."""
    return sorted(k for k in set(saved) | set(now) if saved.get(k) != now.get(k))
