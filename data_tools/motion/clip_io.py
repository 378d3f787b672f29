"""Converted clips on disk: one ``.npz`` per clip (docs/reference/file_formats.md).

Arrays: ``poses`` T x 40 (fitted body-model poses), ``markers`` T x 15 x 3 (the
mocap's own joints: ground truth, mm), ``model_markers`` T x 15 x 3 (the
model's markers at the fitted poses, mm), ``fps``, ``shape`` (the body shape as
JSON text), ``source`` (the mocap file), ``dof_names``, ``marker_names``.
No pickled objects: the file loads with ``allow_pickle=False``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_tools.io.checks import body_shape, checked_motion, checked_text, load_npz
from data_tools.io.textfiles import parse_json
from data_tools.motion.retarget import RetargetResult
from tracker.core.body import DOF_NAMES, MARKER_NAMES, BodyModel, BodyShape, fifteen_cone_model
from tracker.core.errors import InputError


@dataclass
class ConvertedClip:
    poses: np.ndarray
    markers: np.ndarray
    model_markers: np.ndarray
    fps: float
    shape: BodyShape
    source: str

    @property
    def model(self) -> BodyModel:
        return fifteen_cone_model(self.shape)

    @property
    def n_frames(self) -> int:
        return self.poses.shape[0]


def save_converted_clip(result: RetargetResult, path: str | Path) -> None:
    np.savez_compressed(
        path, poses=result.poses, markers=result.markers, model_markers=result.model_markers,
        fps=np.float64(result.fps), shape=np.array(result.model.shape.to_json()), source=np.array(result.source),
        dof_names=np.array(result.model.dof_names), marker_names=np.array(result.model.marker_names),
    )


def load_converted_clip(path: str | Path) -> ConvertedClip:
    """Read and validate a converted clip; every array is checked for type, shape and range, errors name the key."""
    path = Path(path)
    arrays = load_npz(path, "converted clip", ("poses", "markers", "model_markers", "fps", "shape"))
    poses, (markers, model_markers), fps = checked_motion(arrays, path, len(DOF_NAMES), ("markers", "model_markers"))
    shape = body_shape(parse_json(checked_text(arrays, "shape", path), path, "shape"), path)
    source = checked_text(arrays, "source", path) if "source" in arrays else ""
    if "dof_names" in arrays and checked_text(arrays, "dof_names", path, ndim=1) != DOF_NAMES:
        raise InputError("pose layout differs from this version's 40-dof layout", path)
    if "marker_names" in arrays and checked_text(arrays, "marker_names", path, ndim=1) != list(MARKER_NAMES):
        raise InputError("marker set differs from this version's 15 markers", path)
    return ConvertedClip(poses, markers, model_markers, fps, shape, source)
