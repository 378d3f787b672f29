"""Camera calibration files: our ``cameras.json`` (docs/reference/file_formats.md) and PARSEC bodytrack's
``CameraK.cal`` (Bouguet's calibration-toolbox order). The camera model itself is :mod:`tracker.core.cameras`."""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from data_tools.io.checks import (
    MAX_DISTORTION, MAX_FOCAL_PX, MAX_IMAGE_SIDE, MAX_POSITION_MM, MAX_PRINCIPAL_PX, MAX_SKEW, check_range,
    number_array, real_number,
)
from data_tools.io.textfiles import read_json, read_numbers
from tracker.core.cameras import Camera, CameraRig, make_camera
from tracker.core.errors import InputError
from tracker.core.rotations import exp_map_to_matrix


#: Camera names become folder names (``images/<camera>/``): no separators, no leading dot.
_CAMERA_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}")


def checked_camera(name: Any, width: Any, height: Any, fx: Any, fy: Any, cx: Any, cy: Any, R: Any, t: Any,
                   skew: Any = 0.0, dist: Any = (0, 0, 0, 0, 0), source: str | Path | None = None) -> Camera:
    """:func:`~tracker.core.cameras.make_camera` after refusing implausible values, with the range in the message.

    Ranges: width and height positive integers up to :data:`~data_tools.io.checks.MAX_IMAGE_SIDE`
    pixels, focal lengths positive up to ``MAX_FOCAL_PX``, principal point within
    ``±MAX_PRINCIPAL_PX``, skew within ``±MAX_SKEW``, distortion within
    ``±MAX_DISTORTION``, translation within ``±MAX_POSITION_MM`` mm; ``R`` a rotation.
    """
    if not isinstance(name, str) or not _CAMERA_NAME.fullmatch(name):
        raise InputError(f"camera name must be 1 to 64 letters, digits, '_', '-' or '.' (it names a folder), "
                         f"got {name!r}"[:160], source)
    label = f"camera {name!r}"
    scalars = {"width": width, "height": height, "fx": fx, "fy": fy, "cx": cx, "cy": cy, "skew": skew}
    for key, value in scalars.items():  # numbers (not text, lists or inf) before make_camera converts them
        real_number(value, f"{label}: {key}", source)
    R, t, dist = (number_array(v, f"{label}: {k}", source) for k, v in (("R", R), ("t", t), ("dist", dist)))
    check_range(R, f"{label}: R", source, hi=2.0)  # a rotation has entries in [-1, 1]; keeps R R^T finite
    with np.errstate(all="ignore"):  # a degenerate R makes det() warn before make_camera refuses it
        cam = make_camera(name, width, height, fx, fy, cx, cy, R, t, skew, dist,
                          source=None if source is None else str(source))
    for key, hi, positive, unit in (("width", MAX_IMAGE_SIDE, True, " px"), ("height", MAX_IMAGE_SIDE, True, " px"),
                                    ("fx", MAX_FOCAL_PX, True, " px"), ("fy", MAX_FOCAL_PX, True, " px"),
                                    ("cx", MAX_PRINCIPAL_PX, False, " px"), ("cy", MAX_PRINCIPAL_PX, False, " px"),
                                    ("skew", MAX_SKEW, False, "")):
        check_range(getattr(cam, key), f"{label}: {key}", source, hi=hi, positive=positive, unit=unit)
    check_range(cam.dist, f"{label}: dist", source, hi=MAX_DISTORTION)
    check_range(cam.t, f"{label}: t", source, hi=MAX_POSITION_MM, unit=" mm")
    return cam


def read_cameras_json(path: str | Path) -> CameraRig:
    """Read ``cameras.json`` (docs/reference/file_formats.md); every value is checked (:func:`checked_camera`)."""
    path = Path(path)
    doc = read_json(path, "camera file")
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
        out.append(checked_camera(c["name"], c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"], c["R"],
                                  c["t"], c.get("skew", 0.0), c.get("dist", (0, 0, 0, 0, 0)), source=path))
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
    cam = checked_camera(name or path.stem, width, height, fc[0], fc[1], cc[0], cc[1], R, T, skew=alpha, dist=kc,
                         source=path)
    check_range(om, "om (Rodrigues vector)", path, hi=2 * np.pi, unit=" rad")
    diff = np.abs(exp_map_to_matrix(om) - R).max()
    if diff > 1e-3:
        raise InputError(f"R and om (its Rodrigues vector) disagree by {diff:.3g}", path)
    return cam
