"""Whitespace-separated number files (calibrations, body shapes, poses)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from tracker.core.errors import InputError


def read_numbers(path: str | Path, what: str) -> np.ndarray:
    """All numbers of a text file, flat, as float64; unreadable files, words and NaN/inf are refused."""
    path = Path(path)
    try:
        tokens = path.read_text().split()
    except OSError as exc:
        raise InputError(f"cannot read {what}: {exc.strerror}", path) from None
    try:
        values = np.array([float(x) for x in tokens])
    except ValueError as exc:
        raise InputError(f"non-numeric value in {what} ({exc})", path) from None
    if not np.all(np.isfinite(values)):
        raise InputError(f"{what} contains NaN or infinite values", path)
    return values
