"""Writing output files so that a failure never leaves one half-written."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from tracker.core.errors import InputError


def current_umask() -> int:
    """The process's file-mode creation mask (read from ``/proc`` where it can be, so no other thread ever sees
    it changed)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def follow_umask(path: str | Path, directory: bool = False) -> None:
    """Give ``path`` the mode a plain ``open`` (``0o666``) or ``mkdir`` (``0o777``) would have given it under the
    umask: temporary files and folders are created private (``0o600``, ``0o700``) whatever the umask."""
    os.chmod(path, (0o777 if directory else 0o666) & ~current_umask())


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` when the block succeeds, removed
    when it fails (or is interrupted). The suffix is kept, so writers that choose a format by it still do; the
    file gets the mode the umask gives new files."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    except OSError as exc:
        raise InputError(f"cannot write here ({exc.strerror})", path) from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        follow_umask(tmp_path)
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | Path, text: str) -> None:
    """``path`` holds ``text`` (UTF-8) in full or is left as it was."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _writable_ancestor(path: Path, what: str) -> None:
    """Refuse ``path`` when the nearest existing ancestor is a file or not writable (checked up front, before
    any long work)."""
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"cannot write {what} here: {parent} is a file, not a folder", path)
    if not os.access(parent, os.W_OK | os.X_OK) or not _can_create_in(parent):
        raise InputError(f"cannot write {what} here: {parent} is not writable", path)


def _can_create_in(folder: Path) -> bool:
    """Whether a file can really be created in ``folder`` (a probe, removed at once): ``os.access`` says yes to
    root everywhere, and to read-only or virtual file systems such as ``/proc``."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


def check_output_file(path: str | Path, what: str = "the output file", suffixes: tuple[str, ...] = ()) -> Path:
    """``path`` as a place a file can be written: not a folder, under a writable folder, with one of
    ``suffixes`` (lower case, with the dot) when given."""
    path = Path(path)
    if suffixes and path.suffix.lower() not in suffixes:
        raise InputError(f"{what} must end in {' or '.join(suffixes)}", path)
    if path.is_dir():
        raise InputError(f"{what} is a folder, not a file", path)
    _writable_ancestor(path, what)
    return path


def check_output_folder(path: str | Path, what: str = "the output folder", empty: bool = False,
                        replaceable: tuple[str, ...] = ()) -> Path:
    """``path`` as a folder to write into: not a file, under a writable folder, and (``empty``) without
    contents. With ``replaceable`` (file names), a non-empty folder may be replaced only if it holds one of
    them (it is one of ours, e.g. a sequence with its ``cameras.json``), never any other folder."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{what} is a file, not a folder", path)
    if path.is_dir() and any(path.iterdir()):
        if empty:
            raise InputError(f"{what} is not empty (pass --overwrite to replace it)", path)
        if replaceable and not any((path / name).exists() for name in replaceable):
            raise InputError(f"{what} is not empty and holds no {' or '.join(replaceable)}: refusing to replace "
                             "a folder this program did not write", path)
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK) or not _can_create_in(path):
            raise InputError(f"cannot write in {what}: not writable", path)
    else:
        _writable_ancestor(path, what)
    return path
