"""Calibration files of other tools, read into (and written from) a :class:`~tracker.core.cameras.CameraRig`.

Formats (each camera ends as this toolkit's model: pixels, world-to-camera ``R``, ``t`` in millimetres):

* **TOML** of Pose2Sim and anipose-style tools: one table per camera with ``name``, ``size`` [width, height] (px),
  ``matrix`` (3x3 intrinsics, px), ``distortions`` [k1, k2, p1, p2(, k3)] (OpenCV's model), ``rotation``
  (Rodrigues vector, world to camera) and ``translation`` (metres, world to camera); a ``[metadata]`` table is
  skipped. Fisheye cameras are refused (this camera model has no fisheye distortion).
* **Qualisys** ``.qca.txt`` (XML exported by Qualisys Track Manager): per ``<camera>``, ``<transform>`` is the
  camera's position in the world (``x y z``, mm) and the world-to-camera rotation ``r11..r33`` in Qualisys'
  camera axes (x right, y up, z backwards), ``<intrinsic>`` is in sensor sub-pixel units (the ratio of the sensor's
  range ``sensorMaxU - sensorMinU`` to the pixel range of ``<fov_marker_max>``, 64 on the example), and the image
  is the ``<fov_video>`` window. Its distortion coefficients are used as they are (normalised coordinates).
* **OpenCV FileStorage** (``.yml``, ``.yaml``, ``.xml``) in the layout of EasyMocap-style tools: ``names`` (a
  list of camera names), and per camera ``K_<name>`` (3x3), ``dist_<name>`` (1x4 or 1x5), ``R_<name>``
  (Rodrigues vector) or ``Rot_<name>`` (3x3), ``T_<name>`` (3x1), optionally ``size_<name>`` [width, height]; a
  scalar ``unit`` of ``"m"`` (the default) or ``"mm"`` says what ``T`` is in. Intrinsics and extrinsics may be
  in one file or in two (give both).
* **cameras.json**, this toolkit's own (:mod:`data_tools.sequences.calibration`).

:func:`read_rig` picks the reader by the file's name. Image sizes missing from a file (OpenCV files often lack
them) come from ``sizes`` (the videos' sizes, for instance). Every problem is one :class:`InputError` naming the
file.
"""
from __future__ import annotations

import os
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, Mapping, Sequence

import cv2
import numpy as np

from data_tools.io.checks import number_array
from data_tools.sequences.calibration import checked_camera, read_cameras_json, write_cameras_json
from tracker.core.cameras import Camera, CameraRig
from tracker.core.errors import InputError

#: Qualisys camera axes (x right, y up, z backwards) to OpenCV's (x right, y down, z forwards).
_QUALISYS_TO_OPENCV = np.diag([1.0, -1.0, -1.0])
#: Pixel sizes of a camera: name -> (width, height).
Sizes = Mapping[str, tuple[int, int]]

FORMATS = ("toml", "qca", "opencv", "json")


def calibration_format(path: str | Path) -> str:
    """The format of a calibration file from its name: one of :data:`FORMATS`."""
    name = Path(path).name.lower()
    if name.endswith(".qca.txt") or name.endswith(".qca"):
        return "qca"
    suffix = Path(name).suffix
    if suffix == ".toml":
        return "toml"
    if suffix == ".json":
        return "json"
    if suffix in (".yml", ".yaml"):
        return "opencv"
    if suffix == ".xml":
        return "qca" if _xml_root_tag(Path(path)) == "calibration" else "opencv"
    raise InputError("unknown calibration format: expected .toml (Pose2Sim, anipose), .qca.txt (Qualisys), "
                     ".yml/.yaml/.xml (OpenCV FileStorage) or .json (cameras.json)", path)


def read_rig(paths: str | Path | Sequence[str | Path], sizes: Sizes | None = None) -> CameraRig:
    """Read a calibration in any of :data:`FORMATS`; OpenCV's may be two files (intrinsics, extrinsics)."""
    paths = [Path(paths)] if isinstance(paths, (str, os.PathLike)) else [Path(p) for p in paths]
    if not paths:
        raise InputError("no calibration file given")
    kinds = [calibration_format(p) for p in paths]
    if len(paths) > 1 and set(kinds) != {"opencv"}:
        raise InputError("only OpenCV FileStorage calibrations come as several files; give one file", paths[1])
    for p in paths:
        if not p.is_file():
            raise InputError("calibration file does not exist", p)
    kind = kinds[0]
    if kind == "toml":
        return read_toml_rig(paths[0], sizes)
    if kind == "qca":
        return read_qca_rig(paths[0])
    if kind == "json":
        return read_cameras_json(paths[0])
    return read_opencv_rig(paths, sizes)


def write_rig(rig: CameraRig, path: str | Path) -> None:
    """Write ``rig`` in the format that ``path``'s name says (:func:`calibration_format`)."""
    kind = calibration_format(path)
    {"toml": write_toml_rig, "qca": write_qca_rig, "opencv": write_opencv_rig, "json": write_cameras_json}[kind](
        rig, path)


# ---------------------------------------------------------------------------
# TOML (Pose2Sim, anipose)
# ---------------------------------------------------------------------------

def _size(value: Any, label: str, path: Path, sizes: Sizes | None, name: str) -> tuple[Any, Any]:
    if value is None:
        if sizes is None or name not in sizes:
            raise InputError(f"{label}: the file gives no image size (give the videos, whose size is used)", path)
        return sizes[name]
    size = number_array(value, f"{label}: size", path).ravel()
    if size.size != 2:
        raise InputError(f"{label}: size must be [width, height], got {size.size} numbers", path)
    return size[0], size[1]


def _intrinsics(K: Any, label: str, path: Path) -> np.ndarray:
    K = number_array(K, f"{label}: matrix", path)
    if K.shape != (3, 3):
        raise InputError(f"{label}: the intrinsic matrix must be 3x3, got shape {K.shape}", path)
    if not np.all(np.isfinite(K)) or abs(K[2, 2]) < 1e-12 or np.abs(K[2, :2]).max() > 1e-9 or abs(K[1, 0]) > 1e-9:
        raise InputError(f"{label}: the intrinsic matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]]", path)
    return K / K[2, 2]


def _camera_from_opencv(name: str, size: tuple[Any, Any], K: np.ndarray, dist: Any, rvec_or_R: Any, t_mm: Any,
                        label: str, path: Path) -> Camera:
    """A camera from OpenCV-style parameters: ``K`` (px), ``dist``, a Rodrigues vector or 3x3 ``R``, ``t`` (mm)."""
    R = number_array(rvec_or_R, f"{label}: rotation", path)
    if R.size == 3:
        if not np.all(np.isfinite(R)) or np.abs(R).max() > 2 * np.pi:
            raise InputError(f"{label}: the rotation vector must be 3 finite numbers within ±2π rad", path)
        R = cv2.Rodrigues(R.reshape(3, 1))[0]
    elif R.shape != (3, 3):
        raise InputError(f"{label}: rotation must be a Rodrigues vector (3) or a 3x3 matrix, got shape {R.shape}",
                         path)
    dist = number_array(dist, f"{label}: distortions", path).ravel()
    t = number_array(t_mm, f"{label}: translation", path).ravel()
    skew = K[0, 1] / K[0, 0] if K[0, 0] else 0.0
    return checked_camera(name, size[0], size[1], K[0, 0], K[1, 1], K[0, 2], K[1, 2], R, t, skew=skew, dist=dist,
                          source=path)


def read_toml_rig(path: str | Path, sizes: Sizes | None = None) -> CameraRig:
    """Pose2Sim's / anipose's TOML calibration (module docstring); translations metres -> mm."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read calibration: {exc}", path) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", path) from None
    cams = []
    for key, table in doc.items():
        if key == "metadata":
            continue
        label = f"camera table [{key}]"
        if not isinstance(table, dict):
            raise InputError(f"{label} is not a table", path)
        missing = [k for k in ("matrix", "distortions", "rotation", "translation") if k not in table]
        if missing:
            raise InputError(f"{label} lacks {', '.join(missing)}", path)
        if table.get("fisheye", False) is True:
            raise InputError(f"{label} is a fisheye camera; this camera model has no fisheye distortion", path)
        name = table.get("name", key)
        size = _size(table.get("size"), label, path, sizes, str(name))
        t_m = number_array(table["translation"], f"{label}: translation", path)
        cams.append(_camera_from_opencv(name, size, _intrinsics(table["matrix"], label, path), table["distortions"],
                                        table["rotation"], t_m * 1000.0, label, path))
    return _rig(cams, path)


def _toml_list(values: np.ndarray) -> str:
    if values.ndim == 1:
        return "[ " + ", ".join(repr(float(v)) for v in values) + "]"
    return "[ " + ", ".join(_toml_list(row) for row in values) + "]"


def write_toml_rig(rig: CameraRig, path: str | Path) -> None:
    """Write ``rig`` as Pose2Sim's TOML (translations in metres)."""
    lines = []
    for c in rig.cameras:
        K = np.array([[c.fx, c.skew * c.fx, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]])
        rvec = cv2.Rodrigues(np.asarray(c.R, float))[0].ravel()
        lines += [f"[{c.name}]", f'name = "{c.name}"', f"size = {_toml_list(np.array([c.width, c.height], float))}",
                  f"matrix = {_toml_list(K)}", f"distortions = {_toml_list(np.asarray(c.dist, float))}",
                  f"rotation = {_toml_list(rvec)}", f"translation = {_toml_list(np.asarray(c.t) / 1000.0)}",
                  "fisheye = false", ""]
    Path(path).write_text("\n".join(lines + ["[metadata]", "adjusted = false", "error = 0.0", ""]))


# ---------------------------------------------------------------------------
# Qualisys .qca.txt
# ---------------------------------------------------------------------------

def _xml_root_tag(path: Path) -> str:
    try:
        for _event, elem in ET.iterparse(str(path), events=("start",)):
            return elem.tag
    except (ET.ParseError, OSError):
        return ""
    return ""


def _attrs(elem: ET.Element | None, keys: Sequence[str], what: str, path: Path) -> list[float]:
    if elem is None:
        raise InputError(f"{what} is missing", path)
    out = []
    for k in keys:
        if k not in elem.attrib:
            raise InputError(f"{what} lacks the attribute {k!r}", path)
        try:
            out.append(float(elem.attrib[k]))
        except ValueError:
            raise InputError(f"{what}: {k} must be a number, got {elem.attrib[k]!r}"[:160], path) from None
        if not np.isfinite(out[-1]):
            raise InputError(f"{what}: {k} must be finite, got {elem.attrib[k]!r}", path)
    return out


def read_qca_rig(path: str | Path) -> CameraRig:
    """A Qualisys ``.qca.txt`` calibration (module docstring): camera pose and sub-pixel intrinsics converted."""
    path = Path(path)
    try:
        root = ET.parse(str(path)).getroot()
    except ET.ParseError as exc:
        raise InputError(f"not valid XML: {exc}", path) from None
    except OSError as exc:
        raise InputError(f"cannot read calibration: {exc.strerror or exc}", path) from None
    if root.tag != "calibration":
        raise InputError(f"not a Qualisys calibration: the XML root is <{root.tag}>, not <calibration>", path)
    cams = []
    for i, cam in enumerate(root.iter("camera")):
        if cam.attrib.get("active", "1") == "0":
            continue
        name = cam.attrib.get("serial", f"cam{i + 1}")
        label = f"camera {name!r}"
        tr = _attrs(cam.find("transform"), [f"r{a}{b}" for a in "123" for b in "123"] + ["x", "y", "z"],
                    f"{label}: <transform>", path)
        pose = np.array(tr[:9]).reshape(3, 3)
        position = np.array(tr[9:])
        keys = ("focalLengthU", "focalLengthV", "centerPointU", "centerPointV", "sensorMinU", "sensorMaxU",
                "sensorMinV", "sensorMaxV")
        fu, fv, cu, cv, smin_u, smax_u, smin_v, smax_v = _attrs(cam.find("intrinsic"), keys,
                                                                f"{label}: <intrinsic>", path)
        intr = cam.find("intrinsic")
        dist = [float(intr.attrib.get(k, 0.0)) for k in ("radialDistortion1", "radialDistortion2",
                                                          "tangentalDistortion1", "tangentalDistortion2",
                                                          "radialDistortion3")]
        full = _attrs(cam.find("fov_marker_max"), ("left", "top", "right", "bottom"), f"{label}: <fov_marker_max>",
                      path)
        video = _attrs(cam.find("fov_video"), ("left", "top", "right", "bottom"), f"{label}: <fov_video>", path)
        if full[2] <= full[0] or full[3] <= full[1] or smax_u <= smin_u or smax_v <= smin_v:
            raise InputError(f"{label}: empty sensor or field of view", path)
        scale_u, scale_v = (smax_u - smin_u) / (full[2] - full[0]), (smax_v - smin_v) / (full[3] - full[1])
        R = _QUALISYS_TO_OPENCV @ pose
        if np.abs(R @ R.T - np.eye(3)).max() > 1e-4:
            raise InputError(f"{label}: <transform> is not a rotation", path)
        # re-orthonormalise the exported 16-digit matrix so that the camera model's 1e-5 check holds
        u, _, vt = np.linalg.svd(R)
        R = u @ vt
        K = np.array([[fu / scale_u, 0.0, cu / scale_u - video[0]], [0.0, fv / scale_v, cv / scale_v - video[1]],
                      [0.0, 0.0, 1.0]])
        size = (int(round(video[2] - video[0] + 1)), int(round(video[3] - video[1] + 1)))
        cams.append(_camera_from_opencv(name, size, K, dist, R, -R @ position, label, path))
    return _rig(cams, path)


def write_qca_rig(rig: CameraRig, path: str | Path, subpixels: int = 64) -> None:
    """Write ``rig`` as a Qualisys ``.qca.txt`` (``subpixels`` sensor units per pixel; no skew)."""
    root = ET.Element("calibration", {"source": "pose-tracker", "type": "regular"})
    cameras = ET.SubElement(root, "cameras")
    for c in rig.cameras:
        if c.skew:
            raise InputError(f"camera {c.name!r} has skew, which a .qca.txt file cannot hold", path)
        cam = ET.SubElement(cameras, "camera", {"active": "1", "serial": c.name, "viewrotation": "0"})
        box = {"left": "0", "top": "0", "right": str(c.width - 1), "bottom": str(c.height - 1)}
        for tag in ("fov_marker", "fov_marker_max", "fov_video", "fov_video_max"):
            ET.SubElement(cam, tag, box)
        pose = _QUALISYS_TO_OPENCV @ np.asarray(c.R)
        attrs = {f"r{a + 1}{b + 1}": repr(float(pose[a, b])) for a in range(3) for b in range(3)}
        attrs.update(zip("xyz", (repr(float(v)) for v in c.centre)))
        ET.SubElement(cam, "transform", attrs)
        k1, k2, p1, p2, k3 = c.dist
        ET.SubElement(cam, "intrinsic", {
            "focalLengthU": repr(c.fx * subpixels), "focalLengthV": repr(c.fy * subpixels),
            "centerPointU": repr(c.cx * subpixels), "centerPointV": repr(c.cy * subpixels),
            "sensorMinU": "0", "sensorMaxU": str((c.width - 1) * subpixels), "sensorMinV": "0",
            "sensorMaxV": str((c.height - 1) * subpixels), "skew": "0", "radialDistortion1": repr(k1),
            "radialDistortion2": repr(k2), "radialDistortion3": repr(k3), "tangentalDistortion1": repr(p1),
            "tangentalDistortion2": repr(p2)})
    ET.indent(root)
    ET.ElementTree(root).write(str(path), encoding="ascii", xml_declaration=True)


# ---------------------------------------------------------------------------
# OpenCV FileStorage (EasyMocap-style layout)
# ---------------------------------------------------------------------------

def _storage_nodes(path: Path) -> dict[str, Any]:
    """Every top-level node of an OpenCV FileStorage file: matrices as arrays, strings, numbers, string lists."""
    from data_tools.sequences.sequence import _stderr_silenced

    with _stderr_silenced():
        try:
            fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        except (cv2.error, SystemError):  # OpenCV's parser errors surface as either
            fs = None
        if fs is None or not fs.isOpened():
            raise InputError("cannot read as an OpenCV FileStorage file (YAML with a %YAML:1.0 line, or XML)", path)
        try:
            root = fs.root()
            out: dict[str, Any] = {}
            for key in root.keys():
                node = root.getNode(key)
                if node.isSeq():
                    out[key] = [node.at(i).string() if node.at(i).isString() else node.at(i).real()
                                for i in range(node.size())]
                elif node.isString():
                    out[key] = node.string()
                elif node.isReal() or node.isInt():
                    out[key] = node.real()
                else:
                    out[key] = node.mat()
        except cv2.error as exc:
            raise InputError(f"malformed OpenCV FileStorage file: {str(exc).strip().splitlines()[-1]}"[:200],
                             path) from None
        finally:
            fs.release()
    return out


def read_opencv_rig(paths: str | Path | Sequence[str | Path], sizes: Sizes | None = None) -> CameraRig:
    """OpenCV FileStorage calibration in one file or two (module docstring); ``T`` in ``unit`` (default m)."""
    paths = [Path(paths)] if isinstance(paths, (str, os.PathLike)) else [Path(p) for p in paths]
    nodes: dict[str, Any] = {}
    where: dict[str, Path] = {}
    for p in paths:
        for k, v in _storage_nodes(p).items():
            nodes[k], where[k] = v, p
    first = paths[0]
    names = nodes.get("names")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise InputError('expected a "names" list of camera names', first)
    unit = nodes.get("unit", "m")
    if unit not in ("m", "mm"):
        raise InputError(f'unit must be "m" or "mm", got {unit!r}'[:120], where.get("unit", first))
    to_mm = 1000.0 if unit == "m" else 1.0
    cams = []
    for name in names:
        label = f"camera {name!r}"
        need = [f"K_{name}", f"T_{name}"]
        rot = f"Rot_{name}" if f"Rot_{name}" in nodes else f"R_{name}"
        missing = [k for k in need + [rot] if nodes.get(k) is None]
        if missing:
            raise InputError(f"{label}: no {', '.join(missing)} in the file(s)", first)
        src = where[f"K_{name}"]
        size = _size(nodes.get(f"size_{name}"), label, src, sizes, name)
        dist = nodes.get(f"dist_{name}")
        cams.append(_camera_from_opencv(name, size, _intrinsics(nodes[f"K_{name}"], label, src),
                                        np.zeros(5) if dist is None else dist, nodes[rot],
                                        np.asarray(nodes[f"T_{name}"], float) * to_mm, label, where[f"T_{name}"]))
    return _rig(cams, first)


def camera_names(paths: str | Path | Sequence[str | Path]) -> list[str]:
    """The camera names of an OpenCV FileStorage calibration (its ``names`` list), read without the cameras."""
    paths = [Path(paths)] if isinstance(paths, (str, os.PathLike)) else [Path(p) for p in paths]
    names = _storage_nodes(paths[0]).get("names")
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise InputError('expected a "names" list of camera names', paths[0])
    return names


def write_opencv_rig(rig: CameraRig, path: str | Path) -> None:
    """Write ``rig`` as one OpenCV FileStorage file (YAML or XML by the name), ``T`` in metres."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("unit", "m")
    fs.startWriteStruct("names", cv2.FileNode_SEQ)
    for c in rig.cameras:
        fs.write("", c.name)
    fs.endWriteStruct()
    for c in rig.cameras:
        fs.write(f"K_{c.name}", np.array([[c.fx, c.skew * c.fx, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]]))
        fs.write(f"dist_{c.name}", np.asarray(c.dist, float).reshape(1, 5))
        fs.write(f"Rot_{c.name}", np.asarray(c.R, float))
        fs.write(f"T_{c.name}", (np.asarray(c.t, float) / 1000.0).reshape(3, 1))
        fs.write(f"size_{c.name}", np.array([[c.width, c.height]], float))
    fs.release()


def _rig(cams: list[Camera], path: Path) -> CameraRig:
    if not cams:
        raise InputError("no cameras in the calibration", path)
    names = [c.name for c in cams]
    if len(set(names)) != len(names):
        raise InputError(f"camera names must be unique, got {names}", path)
    return CameraRig(cams)
