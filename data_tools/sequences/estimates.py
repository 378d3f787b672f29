"""Pose files: ``estimates.npz`` written by ``track`` (``poses`` T x D, ``markers`` T x 15 x 3, ``best_poses``)
and the ``--init`` / ``--poses`` files read back (any .npz with a ``poses`` array)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from data_tools.io.checks import MAX_POSITION_MM, checked_array, load_npz
from tracker.core.body import BodyModel


def read_poses_file(path: str | Path, what: str = "poses", model: BodyModel | None = None) -> np.ndarray:
    """The ``poses`` array ``T x D`` (T >= 1) of an .npz (``estimates.npz``, ``--init``), checked for type and
    plausible range; with ``model`` its pose layout is checked too."""
    arrays = load_npz(path, what, ("poses",))
    width = "D" if model is None else model.n_dofs
    return checked_array(arrays, "poses", path, ("T", width), hi=MAX_POSITION_MM, unit=" mm or rad")


def write_estimates(path: str | Path, poses: np.ndarray, markers: np.ndarray, best_poses: np.ndarray) -> None:
    """``estimates.npz``: mean poses ``T x D``, their markers ``T x 15 x 3`` (mm) and the best particles
    ``T x D`` (the known frames first in each)."""
    np.savez(path, poses=poses, markers=markers, best_poses=best_poses)
