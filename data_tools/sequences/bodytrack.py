"""Readers for PARSEC bodytrack's text files: body shape, poses, pose parameters.

The folder layout (``CALIB/CameraK.cal``, ``CAMK/imageNNNN.bmp``,
``FGK/imageNNNN.bmp``) is read by :mod:`data_tools.sequences.sequence`; this module
reads the numbers that define the 10-cone body model and its poses.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tracker.core.body import BodyModel
from tracker.core.errors import InputError
from tracker.core.parsec_body import BODYTRACK_DOF_NAMES, ten_cone_model
from data_tools.io.checks import MAX_BODY_MM, MAX_POSITION_MM
from data_tools.io.textfiles import read_numbers

N_POSE = len(BODYTRACK_DOF_NAMES)


def read_body_shape(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``BodyShapeParameters.txt`` -> (limbs ``10 x 4``, lengths ``(18,)``), mm."""
    v = read_numbers(path, "body shape file", MAX_BODY_MM, " mm")
    if v.size != 58:
        raise InputError(f"expected 58 numbers (10 cones x 4, then 18 lengths), found {v.size}", path)
    return v[:40].reshape(10, 4), v[40:]


def read_poses(path: str | Path) -> np.ndarray:
    """A pose file (``InitialPose.txt``, or one pose of 31 numbers per line) -> ``T x 31``."""
    v = read_numbers(path, "pose file", MAX_POSITION_MM, " mm or rad")
    if v.size == 0 or v.size % N_POSE:
        raise InputError(f"expected a multiple of {N_POSE} numbers (one bodytrack pose each), found {v.size}", path)
    return v.reshape(-1, N_POSE)


@dataclass
class PoseParameters:
    """``PoseParameters.txt``: random-walk standard deviations and limits of the 31 pose numbers."""

    std: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


def read_pose_parameters(path: str | Path) -> PoseParameters:
    v = read_numbers(path, "pose parameter file", MAX_POSITION_MM, " mm or rad")
    if v.size != 3 * N_POSE:
        raise InputError(f"expected {3 * N_POSE} numbers (31 std devs, 31 lower, 31 upper limits), found {v.size}",
                         path)
    std, lower, upper = v[:N_POSE], v[N_POSE:2 * N_POSE], v[2 * N_POSE:]
    if np.any(std < 0):
        raise InputError("standard deviations must not be negative", path)
    if np.any(lower > upper):
        i = int(np.argmax(lower > upper))
        raise InputError(f"lower limit above upper limit for {BODYTRACK_DOF_NAMES[i]}", path)
    return PoseParameters(std, lower, upper)


def bodytrack_model(folder: str | Path, use_limits: bool = False) -> tuple[BodyModel, PoseParameters | None]:
    """The 10-cone model of a bodytrack folder, and its ``PoseParameters.txt`` when present.

    The model's pose limits are unbounded unless ``use_limits``: the limits
    shipped with sequenceB_1 exclude the sequence's own ``InitialPose.txt`` in
    14 of 31 numbers (PARSEC's tracker has its limit check switched off, saying
    it can be enabled "if valid pose extent parameters are present").
    """
    folder = Path(folder)
    shape_file = folder / "BodyShapeParameters.txt"
    if not shape_file.exists():
        raise InputError("bodytrack folder lacks BodyShapeParameters.txt", folder)
    limbs, lengths = read_body_shape(shape_file)
    params = None
    if (folder / "PoseParameters.txt").exists():
        params = read_pose_parameters(folder / "PoseParameters.txt")
    limited = use_limits and params is not None
    model = ten_cone_model(limbs, lengths, params.lower if limited else None, params.upper if limited else None,
                           source=str(shape_file))
    return model, params
