"""Writing output files so that a failure never leaves one half-written."""
from __future__ import annotations

import errno
import os
import secrets
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from tracker.core.errors import InputError


#: Why a write failed, by ``errno``: the causes a user can act on (free space, another disk, permissions).
WRITE_FAILURES = {
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large for the file system",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
}


def is_write_failure(exc: BaseException) -> bool:
    """Whether ``exc`` is a failed write (no space, read-only, no permission), not a bug or a bad input."""
    return isinstance(exc, OSError) and exc.errno in WRITE_FAILURES


def write_failure(path: str | Path, exc: OSError, kept: str = "") -> InputError:
    """The one-line error for a write to ``path`` that failed with ``exc`` (``kept`` says what stays usable,
    e.g. "the previous checkpoint is kept")."""
    cause = WRITE_FAILURES.get(exc.errno) or exc.strerror or str(exc)
    return InputError(f"cannot write: {cause}{'; ' + kept if kept else ''}", path)


@contextmanager
def writing(path: str | Path, kept: str = "") -> Iterator[None]:
    """A block that writes ``path`` (a file or a folder): a failed write in it (no space, read-only, no
    permission) becomes the one-line :func:`write_failure` naming ``path``; other errors pass unchanged, and so
    does an error that names a file outside ``path``'s folder (a file the block read, not one it wrote)."""
    try:
        yield
    except OSError as exc:
        if not is_write_failure(exc) or not _written_beside(exc.filename, Path(path)):
            raise
        raise write_failure(path, exc, kept) from None


def _written_beside(filename: str | bytes | int | None, path: Path) -> bool:
    """Whether an error's file (None: a write to an open file, which names none) lies in ``path``'s folder, where
    ``path`` and its temporary files are written."""
    if not isinstance(filename, (str, os.PathLike)):
        return True
    return Path(filename).resolve().is_relative_to(path.resolve().parent)


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
def fresh_beside(path: str | Path, suffix: str, directory: bool = False, kept: str = "") -> Iterator[Path]:
    """A new, empty file (or folder, with ``directory``) beside ``path``, ``.<name>.<random><suffix>``, for the
    block to fill and rename into place; removed when the block fails or is interrupted. Its name is chosen before
    it is made, so an exception at any moment (a failed write, Ctrl-C, SIGTERM) finds it and removes it: nothing
    stays behind. A name already taken is never touched: another is drawn. Creating it can fail as
    :func:`atomic_path` says."""
    path = Path(path).absolute()
    stem = path.name if directory else path.stem
    made: Path | None = None
    try:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            while made is None:
                fresh = path.with_name(f".{stem}.{secrets.token_hex(6)}{suffix}")
                made = fresh  # named before it exists: an interrupt from here on finds it
                try:
                    if directory:
                        fresh.mkdir(mode=0o700)
                    else:
                        os.close(os.open(fresh, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
                except FileExistsError:  # another's: left alone, another name drawn
                    made = None
        except OSError as exc:
            raise write_failure(path, exc, kept) from None
        yield made
    except BaseException:
        if made is not None:
            if directory:
                shutil.rmtree(made, ignore_errors=True)
            else:
                made.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_path(path: str | Path, kept: str = "") -> Iterator[Path]:
    """A temporary path beside ``path`` to write to; renamed onto ``path`` when the block succeeds, removed
    when it fails (or is interrupted, at any moment: :func:`fresh_beside`), so the file ``path`` held before
    stays as it was. The suffix is kept, so writers that choose a format by it still do; the file gets the mode
    the umask gives new files. A failed write (no space left, a read-only file system, no permission) is a
    one-line :class:`InputError` naming ``path`` and the cause (:func:`write_failure`; ``kept`` adds what stays
    usable)."""
    path = Path(path)
    with fresh_beside(path, path.suffix, kept=kept) as tmp_path, writing(path, kept):
        yield tmp_path
        follow_umask(tmp_path)
        os.replace(tmp_path, path)


def write_bytes_atomic(path: str | Path, data: bytes, kept: str = "") -> None:
    """``path`` holds ``data`` in full or is left as it was (failures as :func:`atomic_path`)."""
    with atomic_path(path, kept) as tmp:
        tmp.write_bytes(data)


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


def check_output_file(path: str | Path, what: str = "the output file", suffixes: tuple[str, ...] = (),
                      new: bool = False, overwrite_flag: str = "--overwrite") -> Path:
    """``path`` as a place a file can be written: not a folder, under a writable folder, with one of
    ``suffixes`` (lower case, with the dot) when given, and (``new``) not an existing non-empty file unless
    the user says so (``overwrite_flag`` names how, in the refusal)."""
    path = Path(path)
    if suffixes and path.suffix.lower() not in suffixes:
        raise InputError(f"{what} must end in {' or '.join(suffixes)}", path)
    if path.is_dir():
        raise InputError(f"{what} is a folder, not a file", path)
    if new and path.is_file() and path.stat().st_size > 0:
        raise InputError(f"{what} exists (pass {overwrite_flag} to replace it)", path)
    _writable_ancestor(path, what)
    return path


def check_output_folder(path: str | Path, what: str = "the output folder", empty: bool = False,
                        replaceable: tuple[str, ...] = (), overwrite_flag: str = "--overwrite") -> Path:
    """``path`` as a folder to write into: not a file, under a writable folder, and (``empty``) without
    contents (the refusal names ``overwrite_flag``, how the user says to replace it, and says when the folder
    holds a finished run). With ``replaceable``
    (file names), a non-empty folder may be replaced only if it holds one of them (it is one of ours, e.g. a
    sequence with its ``cameras.json``), never any other folder."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{what} is a file, not a folder", path)
    if path.is_dir() and any(path.iterdir()):
        if empty:  # a finished run's folder says so: result.json is written once a run has finished
            held = "holds a finished run (result.json)" if (path / "result.json").is_file() else "is not empty"
            raise InputError(f"{what} {held} (pass {overwrite_flag} to replace it)", path)
        if replaceable and not any((path / name).exists() for name in replaceable):
            raise InputError(f"{what} is not empty and holds no {' or '.join(replaceable)}: refusing to replace "
                             "a folder this program did not write", path)
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK) or not _can_create_in(path):
            raise InputError(f"cannot write in {what}: not writable", path)
    else:
        _writable_ancestor(path, what)
    return path


def check_not_inside(out: str | Path, inputs: dict[str, str | Path]) -> None:
    """Refuse to write ``out`` (a file or a folder) into an input: ``inputs`` maps what each input is (e.g.
    "sequence folder", "mocap file") to its path; ``out`` may be neither the input itself nor inside it (an
    input folder is never written into, whatever ``--overwrite`` says)."""
    target = Path(out).resolve()
    for what, given in inputs.items():
        if target.is_relative_to(Path(given).resolve()):
            raise InputError(f"the output would be written into the {what} {given}; choose an output outside "
                             "the inputs", out)


def first_missing(path: str | Path) -> Path:
    """The outermost of ``path`` and its folders that does not exist yet (``path`` itself if it exists): what
    writing ``path`` creates."""
    path = Path(path).absolute()
    missing = path
    for folder in path.parents:
        if folder.exists():
            break
        missing = folder
    return missing


@contextmanager
def undone_unless_started(*paths: str | Path, on: tuple[type[BaseException], ...] = (InputError, KeyboardInterrupt)
                          ) -> Iterator[dict]:
    """A block that begins a command's work in ``paths`` (folders or files). Ended by one of ``on`` (a refusal,
    an interruption) before the block sets ``state["started"]``, whatever it created there is removed again: a
    path that was not there before (see :func:`first_missing`), or the entries it added to a folder that was; so
    a refused command leaves nothing behind. Once started, what was written stays (a checkpoint to resume from,
    a partial result)."""
    before = {Path(p): (set(os.listdir(p)) if Path(p).is_dir() else None) if Path(p).exists() else False
              for p in paths}
    state = {"started": False}
    try:
        yield state
    except on:
        if not state["started"]:
            for path, was in before.items():
                if was is False:
                    _remove(path)
                elif was is not None and path.is_dir():
                    for name in sorted(set(os.listdir(path)) - was):
                        _remove(path / name)
        raise


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)
