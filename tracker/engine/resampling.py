"""Resampling schemes for particle filters (Douc, Cappé & Moulines 2005), chosen by name from :data:`SCHEMES`.

Each takes normalised weights ``w`` ``(P,)`` and a numpy ``Generator`` and
returns ``P`` indices (sorted) whose expected counts are ``P * w``.
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


def systematic(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    P = len(w)
    return _from_positions(w, (rng.random() + np.arange(P)) / P)


def stratified(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    P = len(w)
    return _from_positions(w, (rng.random(P) + np.arange(P)) / P)


def multinomial(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.sort(_from_positions(w, rng.random(len(w))))


def residual(w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    P = len(w)
    copies = np.floor(P * w).astype(int)
    kept = np.repeat(np.arange(P), copies)
    rest = P - len(kept)
    if rest == 0:
        return kept
    r = P * w - copies
    extra = _from_positions(r / r.sum(), rng.random(rest))
    return np.sort(np.concatenate([kept, extra]))


#: ``indices = scheme(weights, rng)`` by name.
SCHEMES: dict[str, Callable[[np.ndarray, np.random.Generator], np.ndarray]] = {
    "systematic": systematic, "stratified": stratified, "multinomial": multinomial, "residual": residual,
}
