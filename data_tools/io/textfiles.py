"""The one place where text files are read: UTF-8 text, lines, JSON, whitespace-separated numbers.

Every reader of a text format (ASF, AMC, BVH, ``cameras.json``, ``meta.json``,
``.cal`` and the bodytrack text files) goes through :func:`read_text`, so all
of them accept a UTF-8 byte-order mark, refuse binary, Latin-1 or UTF-16 files
with the same one-line :class:`InputError`, and never leak a decoding error.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from data_tools.io.checks import check_range
from tracker.core.errors import InputError


def read_text(path: str | Path, what: str) -> str:
    """The text of a UTF-8 file (a leading byte-order mark is dropped).

    Unreadable files and files that are not UTF-8 text (binary, Latin-1,
    UTF-16, NUL bytes) raise :class:`InputError` naming the file and, for a bad
    byte, its line.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror or exc}", path) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{what} is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                         "save it as UTF-8", path, line) from None
    nul = text.find("\0")
    if nul >= 0:
        raise InputError(f"{what} is not UTF-8 text (NUL character: a binary or UTF-16 file); save it as UTF-8",
                         path, text.count("\n", 0, nul) + 1)
    return text


def read_lines(path: str | Path, what: str) -> list[str]:
    """The lines of a UTF-8 text file (see :func:`read_text`)."""
    return read_text(path, what).splitlines()


def parse_json(text: str, source: str | Path | None, what: str = "JSON") -> Any:
    """Parse JSON text; syntax errors, over-long numbers and over-deep nesting raise :class:`InputError`."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{what} is not valid JSON: {exc.msg} (column {exc.colno})", source, exc.lineno) from None
    except ValueError as exc:  # e.g. an integer literal longer than Python converts
        raise InputError(f"{what} is not valid JSON: {exc}", source) from None
    except RecursionError:
        raise InputError(f"{what} is nested too deeply to be a file of this kind", source) from None


def read_json(path: str | Path, what: str) -> Any:
    """The JSON document of a UTF-8 file (see :func:`read_text` and :func:`parse_json`)."""
    return parse_json(read_text(path, what), path, what)


def parse_floats(tokens: list[str], n: int | None, path: str | Path, line: int, what: str,
                 limit: float | None = None, unit: str = "") -> np.ndarray:
    """Parse ``tokens`` as ``n`` finite numbers (any count if ``n`` is None), each within ``±limit`` if given.

    Errors name the file, the line, ``what`` and the expected count or range.
    """
    try:
        vals = np.array([float(t) for t in tokens])
    except ValueError:
        raise InputError(f"{what}: expected numbers, got {' '.join(tokens)[:60]!r}", path, line) from None
    if n is not None and vals.size != n:
        raise InputError(f"{what}: expected {n} numbers, got {vals.size}", path, line)
    if limit is None and np.isfinite(vals).all():  # the common case, without the cost of a full check
        return vals
    return check_range(vals, what, path, line=line, hi=np.inf if limit is None else limit, unit=unit)


def read_numbers(path: str | Path, what: str, limit: float | None = None, unit: str = "") -> np.ndarray:
    """All whitespace-separated numbers of a UTF-8 text file, flat, as float64, each within ``±limit`` if given.

    Words, NaN/inf and out-of-range values are refused with the file and line.
    """
    lines = read_lines(path, what)
    out: list[np.ndarray] = []
    for k, text in enumerate(lines):
        tokens = text.split()
        if tokens:
            out.append(parse_floats(tokens, None, path, k + 1, what, limit, unit))
    return np.concatenate(out) if out else np.zeros(0)
