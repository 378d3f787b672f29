"""Pose-error metrics over the 15 virtual markers, in mm (estimate and truth ``(..., M, 3)``).

Every metric has one name, used as its key in ``result.json`` (``"metrics"``), in ``table.csv`` and in the
tables' headers (:data:`METRICS`):

* ``mpjpe_abs`` -- **MPJPE, absolute**: the HumanEva marker error (Sigal & Black 2006): per frame
  ``e = 1/M sum_m |x_m - y_m|``, no alignment. A sequence's error is the mean over its frames; over R runs
  (seeds) we report the mean and the sample standard deviation (ddof = 1, as Matlab's ``std``) of the per-run
  means.
* ``mpjpe_rel`` -- **MPJPE, root-relative** (as Human3.6M scores poses; Ionescu et al. 2014): the same after
  subtracting each pose's root (pelvis marker 0) from all its markers,
  ``e_rel = 1/M sum_m |(x_m - x_0) - (y_m - y_0)|``: global position error removed.
* ``pa_mpjpe`` -- **PA-MPJPE** (Procrustes-aligned; mmpose's P-MPJPE, "protocol 2" of Human3.6M papers):
  ``min over s, R, t of 1/M sum_m |s R x_m + t - y_m|`` with ``R`` a rotation (Umeyama's closed form,
  reflections excluded): position, orientation and scale removed, only the articulation is scored.
* ``pck_abs`` -- **3DPCK, absolute** at ``tau`` = 150 mm (MuPoTS-3D's PCK_abs; Moon et al. 2019): the
  percentage of markers closer than ``tau`` to the truth, ``100/M sum_m [|x_m - y_m| < tau]``.
* ``pck_rel`` -- **3DPCK, root-relative** at 150 mm, the 3DPCK of MPI-INF-3DHP (Mehta et al. 2017) and of
  mmpose's ``keypoint_3d_pck`` on root-centred poses: ``100/M sum_m [|(x_m - x_0) - (y_m - y_0)| < tau]``
  (:func:`root_relative_pck`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

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


#: The 3DPCK threshold of MPI-INF-3DHP (Mehta et al. 2017), mmpose and MuPoTS-3D (mm).
PCK_THRESHOLD_MM = 150.0


def pck(estimate: np.ndarray, truth: np.ndarray, threshold_mm: float = PCK_THRESHOLD_MM) -> np.ndarray:
    """Per-frame absolute 3DPCK ``(...)`` in percent for markers ``(..., M, 3)``: the markers closer than
    ``threshold_mm`` to the truth, with no alignment, ``100/M sum_m [|x_m - y_m| < threshold]``."""
    est = np.asarray(estimate, float)
    gt = np.asarray(truth, float)
    marker_error(est, gt)  # the same shape and finiteness checks
    return 100.0 * (np.linalg.norm(est - gt, axis=-1) < threshold_mm).mean(axis=-1)


def root_relative_pck(estimate: np.ndarray, truth: np.ndarray, threshold_mm: float = PCK_THRESHOLD_MM,
                      root: int = PELVIS) -> np.ndarray:
    """Per-frame root-relative 3DPCK ``(...)`` in percent for markers ``(..., M, 3)``, as MPI-INF-3DHP defines it
    (Mehta et al. 2017, "Monocular 3D Human Pose Estimation In The Wild Using Improved CNN Supervision") and
    mmpose computes it (``keypoint_3d_pck`` with ``alignment='none'`` on root-centred poses):

    ``100/M sum_m [ |(x_m - x_root) - (y_m - y_root)| < threshold_mm ]``

    Both poses are translated so that their root marker (the pelvis, marker 0) lies at the origin; nothing is
    rotated or scaled. All ``M`` markers count, the root included (its distance is then 0, as in mmpose, whose
    pose lifters put the root back before scoring); the comparison is strict (``<``), as in mmpose and the
    3DHP evaluation script. The default threshold is 150 mm."""
    est = np.asarray(estimate, float)
    gt = np.asarray(truth, float)
    marker_error(est, gt)
    est = est - est[..., root:root + 1, :]
    gt = gt - gt[..., root:root + 1, :]
    return 100.0 * (np.linalg.norm(est - gt, axis=-1) < threshold_mm).mean(axis=-1)


@dataclass(frozen=True)
class Metric:
    """One metric of :data:`METRICS`: its ``name`` (the key in ``result.json``'s ``"metrics"`` and in
    ``table.csv``), ``title`` (tables and plots), ``unit`` (``"mm"`` or ``"%"``) and ``per_frame(estimate,
    truth)``, the per-frame values ``(...)`` for markers ``(..., M, 3)``."""

    name: str
    title: str
    unit: str
    per_frame: Callable[[np.ndarray, np.ndarray], np.ndarray]


#: Every metric a tracking run reports, in the order of the tables; the first is the primary one.
METRICS: tuple[Metric, ...] = (
    Metric("mpjpe_abs", "MPJPE, absolute (HumanEva marker error)", "mm", marker_error),
    Metric("mpjpe_rel", "MPJPE, root-relative", "mm", lambda e, t: marker_error(e, t, root_aligned=True)),
    Metric("pa_mpjpe", "PA-MPJPE", "mm", procrustes_aligned_error),
    Metric("pck_abs", f"3DPCK at {PCK_THRESHOLD_MM:g} mm, absolute", "%", pck),
    Metric("pck_rel", f"3DPCK at {PCK_THRESHOLD_MM:g} mm, root-relative", "%", root_relative_pck),
)


def frame_metrics(estimate: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
    """Every metric of :data:`METRICS` per frame: name -> values ``(T,)`` for markers ``T x M x 3``."""
    return {m.name: np.asarray(m.per_frame(estimate, truth), float) for m in METRICS}
