"""Camera calibration files: our ``cameras.json`` (DESIGN.md "Sequences on disk") and PARSEC bodytrack's
``CameraK.cal`` (Bouguet's calibration-toolbox order). The camera model itself is :mod:`tracker.core.cameras`."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

import numpy as np

from data_tools.textfiles import read_numbers
from tracker.core.cameras import Camera, CameraRig, make_camera
from tracker.core.errors import InputError
from tracker.core.rotations import exp_map_to_matrix


def read_cameras_json(path: str | Path) -> CameraRig:
    """Read ``cameras.json`` (DESIGN.md "Sequences on disk")."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise InputError(f"cannot read camera file: {exc.strerror}", path) from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", path, exc.lineno) from None
    cams = doc.get("cameras") if isinstance(doc, dict) else None
    if not isinstance(cams, list) or not cams:
        raise InputError('expected an object with a non-empty "cameras" list', path)
    out = []
    required = ("name", "width", "height", "fx", "fy", "cx", "cy", "R", "t")
    for i, c in enumerate(cams):
        if not isinstance(c, dict):
            raise InputError(f"cameras[{i}] is not an object", path)
        missing = [k for k in required if k not in c]
        if missing:
            raise InputError(f"cameras[{i}] lacks {', '.join(missing)}", path)
        out.append(make_camera(c["name"], c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"], c["R"],
                               c["t"], c.get("skew", 0.0), c.get("dist", (0, 0, 0, 0, 0)), source=str(path)))
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise InputError(f"camera names must be unique, got {names}", path)
    return CameraRig(out)


def write_cameras_json(rig: CameraRig | Sequence[Camera], path: str | Path) -> None:
    cams = rig.cameras if isinstance(rig, CameraRig) else list(rig)
    Path(path).write_text(json.dumps({"cameras": [c.to_dict() for c in cams]}, indent=1))


def read_bodytrack_calibration(path: str | Path, name: str | None = None, width: int = 640,
                               height: int = 480) -> Camera:
    """Read a PARSEC bodytrack ``CameraK.cal`` (Bouguet toolbox order, 25 numbers).

    Order: fc(2), cc(2), alpha_c, kc(5), R (9, row-major), T (3, mm), om (3).
    The image size is not in the file; pass it (640 x 480 for the shipped data).
    ``om`` must agree with ``R`` (it is the same rotation as a Rodrigues vector).
    """
    path = Path(path)
    v = read_numbers(path, "calibration file")
    if v.size != 25:
        raise InputError(f"expected 25 numbers (fc2 cc2 alpha1 kc5 R9 T3 om3), found {v.size}", path)
    fc, cc, alpha, kc, R, T, om = v[0:2], v[2:4], v[4], v[5:10], v[10:19].reshape(3, 3), v[19:22], v[22:25]
    cam = make_camera(name or path.stem, width, height, fc[0], fc[1], cc[0], cc[1], R, T, skew=alpha, dist=kc,
                      source=str(path))
    diff = np.abs(exp_map_to_matrix(om) - R).max()
    if diff > 1e-3:
        raise InputError(f"R and om (its Rodrigues vector) disagree by {diff:.3g}", path)
    return cam
