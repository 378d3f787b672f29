"""Resampling schemes for particle filters (Douc, Cappé & Moulines 2005), chosen by name from :data:`SCHEMES`.

Each takes normalised weights ``w`` ``(P,)``, a numpy ``Generator`` and optionally a number of draws ``n``
(default ``P``) and returns ``n`` indices (sorted) whose expected counts are ``n * w``.
Systematic uses one uniform offset, stratified one per stratum, multinomial
``P`` independent draws, residual keeps ``floor(P w)`` copies and draws the
rest multinomially.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


def _from_positions(w: np.ndarray, positions: np.ndarray) -> np.ndarray:
    cum = np.cumsum(w)
    cum[-1] = 1.0
    return np.searchsorted(cum, positions, side="right").clip(0, len(w) - 1)


def systematic(w: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    n = len(w) if n is None else n
    return _from_positions(w, (rng.random() + np.arange(n)) / n)


def stratified(w: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    n = len(w) if n is None else n
    return _from_positions(w, (rng.random(n) + np.arange(n)) / n)


def multinomial(w: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    return np.sort(_from_positions(w, rng.random(len(w) if n is None else n)))


def residual(w: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    n = len(w) if n is None else n
    copies = np.floor(n * w).astype(int)
    kept = np.repeat(np.arange(len(w)), copies)
    rest = n - len(kept)
    if rest == 0:
        return kept
    r = n * w - copies
    extra = _from_positions(r / r.sum(), rng.random(rest))
    return np.sort(np.concatenate([kept, extra]))


#: ``indices = scheme(weights, rng[, n])`` by name.
SCHEMES: dict[str, Callable[..., np.ndarray]] = {
    "systematic": systematic, "stratified": stratified, "multinomial": multinomial, "residual": residual,
}
