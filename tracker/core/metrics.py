"""Pose-error metrics over the 15 virtual markers, in mm (estimate and truth ``(..., M, 3)``).

* **Marker error** (HumanEva, Sigal & Black 2006; also MPJPE over these markers): per frame
  ``e = 1/M sum_m |x_m - y_m|``. A sequence's error is the mean over its frames; over R runs (seeds) we
  report the mean and the sample standard deviation (ddof = 1, as Matlab's ``std``) of the per-run means.
* **Pelvis-relative** marker error: the same after subtracting each pose's pelvis marker (marker 0) from
  all its markers, ``e_rel = 1/M sum_m |(x_m - x_0) - (y_m - y_0)|``: global position error removed.
* **PA-MPJPE** (Procrustes-aligned): ``min over s, R, t of 1/M sum_m |s R x_m + t - y_m|`` with ``R`` a
  rotation (Umeyama's closed form, reflections excluded): position, orientation and scale removed, only
  the articulation is scored.
* **3D PCK at tau** (150 mm by default): the percentage of markers within ``tau`` of the truth,
  ``100/M sum_m [|x_m - y_m| <= tau]``.
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


def procrustes_aligned_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Per-frame PA-MPJPE ``(...)`` in mm: the marker error after the best similarity transform (scale,
    rotation, translation) of each estimate onto its truth (Umeyama 1991), for markers ``(..., M, 3)``."""
    est = np.asarray(estimate, float)
    gt = np.asarray(truth, float)
    marker_error(est, gt)  # the same shape and finiteness checks
    est, gt = np.broadcast_arrays(est, gt)
    mu_x, mu_y = est.mean(axis=-2, keepdims=True), gt.mean(axis=-2, keepdims=True)
    x, y = est - mu_x, gt - mu_y
    cov = np.swapaxes(y, -1, -2) @ x / x.shape[-2]  # (..., 3, 3)
    U, S, Vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones(S.shape)
    D[..., -1] = d
    R = (U * D[..., None, :]) @ Vt
    var_x = (x ** 2).sum(axis=(-1, -2)) / x.shape[-2]
    scale = np.where(var_x > 0, (S * D).sum(axis=-1) / np.where(var_x > 0, var_x, 1.0), 1.0)
    aligned = scale[..., None, None] * x @ np.swapaxes(R, -1, -2) + mu_y
    return np.linalg.norm(aligned - gt, axis=-1).mean(axis=-1)


def pck(estimate: np.ndarray, truth: np.ndarray, threshold_mm: float = 150.0) -> np.ndarray:
    """Per-frame 3D PCK ``(...)`` in percent: markers within ``threshold_mm`` of the truth."""
    est = np.asarray(estimate, float)
    gt = np.asarray(truth, float)
    marker_error(est, gt)
    return 100.0 * (np.linalg.norm(est - gt, axis=-1) <= threshold_mm).mean(axis=-1)
