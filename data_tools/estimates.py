"""Pose files: ``estimates.npz`` written by ``track`` (``poses`` T x D, ``markers`` T x 15 x 3, ``best_poses``)
and the ``--init`` / ``--poses`` files read back (any .npz with a ``poses`` array)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from tracker.core.body import BodyModel
from tracker.core.errors import InputError


def read_poses_file(path: str | Path, what: str = "poses", model: BodyModel | None = None) -> np.ndarray:
    """The ``poses`` array ``T x D`` of an .npz (``estimates.npz``, ``--init``); with ``model`` its layout is
    checked too."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if "poses" not in z.files:
                raise InputError("no 'poses' array in the file", path)
            poses = np.asarray(z["poses"], float)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read {what} ({exc})", path) from None
    if model is not None:
        if poses.ndim != 2 or poses.shape[1] != model.n_dofs:
            raise InputError(f"{what} must be T x {model.n_dofs} for the {model.name} model, got {poses.shape}",
                             path)
        if not np.all(np.isfinite(poses)):
            raise InputError(f"{what} contain NaN or infinite values", path)
    return poses


def write_estimates(path: str | Path, poses: np.ndarray, markers: np.ndarray, best_poses: np.ndarray) -> None:
    """``estimates.npz``: mean poses ``T x D``, their markers ``T x 15 x 3`` (mm) and the best particles
    ``T x D`` (the known frames first in each)."""
    np.savez(path, poses=poses, markers=markers, best_poses=best_poses)
