"""Converted clips on disk: one ``.npz`` per clip (DESIGN.md "Sequences on disk").

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

from data_tools.retarget import RetargetResult
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
    """Read and validate a converted clip; errors name the file and the problem."""
    path = Path(path)
    try:
        data = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read converted clip: {exc}", path) from None
    with data:
        missing = [k for k in ("poses", "markers", "model_markers", "fps", "shape") if k not in data.files]
        if missing:
            raise InputError(f"not a converted clip: lacks {', '.join(missing)}", path)
        poses, markers, model_markers = data["poses"], data["markers"], data["model_markers"]
        fps = float(data["fps"])
        shape = BodyShape.from_json(str(data["shape"]), str(path))
        source = str(data["source"]) if "source" in data.files else ""
        if "dof_names" in data.files and list(data["dof_names"]) != DOF_NAMES:
            raise InputError("pose layout differs from this version's 40-dof layout", path)
        if "marker_names" in data.files and list(data["marker_names"]) != list(MARKER_NAMES):
            raise InputError("marker set differs from this version's 15 markers", path)
    T = poses.shape[0] if poses.ndim == 2 else -1
    if poses.shape != (T, 40) or markers.shape != (T, 15, 3) or model_markers.shape != (T, 15, 3):
        raise InputError(f"inconsistent shapes: poses {poses.shape}, markers {markers.shape}, "
                         f"model_markers {model_markers.shape} (expected T x 40, T x 15 x 3, T x 15 x 3)", path)
    for name, arr in (("poses", poses), ("markers", markers), ("model_markers", model_markers)):
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{name} contain NaN or infinite values", path)
    if not np.isfinite(fps) or fps <= 0:
        raise InputError(f"frame rate must be positive, got {fps}", path)
    return ConvertedClip(poses, markers, model_markers, fps, shape, source)
