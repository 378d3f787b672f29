"""HumanEva marker error (Sigal & Black 2006): mean Euclidean distance over the 15 virtual markers, in mm.

Per frame: the mean over markers of ``|estimate - truth|``. A sequence's error
is the mean over its frames; over R runs (seeds) we report the mean and the
sample standard deviation (ddof = 1, as Matlab's ``std``) of the per-run means.
The root-aligned (relative) variant first subtracts each pose's pelvis marker
(marker 0) from all its markers, which removes global position error.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from tracker.core.errors import InputError

PELVIS = 0


def marker_error(estimate: np.ndarray, truth: np.ndarray, root_aligned: bool = False) -> np.ndarray:
    """Per-frame marker error ``(...)`` in mm for markers ``(..., M, 3)`` (shapes must broadcast)."""
    est = np.asarray(estimate, float)
    gt = np.asarray(truth, float)
    if est.shape[-1] != 3 or gt.shape[-1] != 3 or est.ndim < 2 or gt.ndim < 2:
        raise InputError(f"markers must have shape (..., M, 3); got {est.shape} and {gt.shape}")
    if est.shape[-2] != gt.shape[-2]:
        raise InputError(f"estimate has {est.shape[-2]} markers, ground truth {gt.shape[-2]}")
    try:
        np.broadcast_shapes(est.shape, gt.shape)
    except ValueError:
        raise InputError(f"estimate {est.shape} and ground truth {gt.shape} do not match") from None
    if not (np.all(np.isfinite(est)) and np.all(np.isfinite(gt))):
        raise InputError("markers contain NaN or infinite values")
    if root_aligned:
        est = est - est[..., PELVIS:PELVIS + 1, :]
        gt = gt - gt[..., PELVIS:PELVIS + 1, :]
    return np.linalg.norm(est - gt, axis=-1).mean(axis=-1)


def sequence_error(estimate: np.ndarray, truth: np.ndarray, root_aligned: bool = False) -> float:
    """Mean over frames of the per-frame marker error, for markers ``T x M x 3``."""
    return float(marker_error(estimate, truth, root_aligned).mean())


def summarize_runs(per_run_errors: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (ddof 1; 0 for a single run) of per-run sequence errors (mm)."""
    e = np.asarray(per_run_errors, float).ravel()
    if e.size == 0:
        raise InputError("no runs to summarise")
    return float(e.mean()), float(e.std(ddof=1)) if e.size > 1 else 0.0
