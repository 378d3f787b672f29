"""Keypoints of other tools, read as they are: OpenPose-style JSON per frame and plain arrays.

:func:`import_keypoints` reads one source per camera (or one array of every camera), maps each detector's
points to the body model's keypoints (:func:`data_tools.vision.keypoints.layouts.to_canonical`), converts pixels and
frame numbers to the sequence's, checks the result against the sequence and writes ``seq/keypoints/keypoints.npz``
(:func:`data_tools.sequences.keypoint_file.write_keypoints`).

Sources
-------
**OpenPose JSON** (what OpenPose, Pose2Sim, EasyMocap and Sports2D write): a folder per camera of files such as
``name_000000000012_keypoints.json``; the last number in a file's name is its frame. ``people[i].pose_keypoints_2d``
holds ``J * 3`` numbers, ``(x, y, confidence)`` per point in the detector's layout (``body_25``, ``body_25b``,
``coco_17``, ``halpe_26``, ``blazepose_33``). The layout is given, or inferred from ``J`` where only one layout
has that many points (17, 26, 33; 25 is OpenPose's BODY_25 or its BODY_25B and must be given). A file whose
``people`` is empty found nobody (confidence 0 for that frame). **Of several people, the one with the largest
summed confidence is taken**, frame by frame: the person a single-person tracker follows should be the one most
clearly seen; nothing links people across frames.

**Arrays**: a ``.npy`` of ``T x V x J x 3`` (``T x J x 3`` for one camera), its layout given or inferred as above,
or an ``.npz`` with ``points`` of that shape and optionally ``layout`` (a string) and ``cameras`` (``(V,)`` the
camera names of its views). Row ``k`` is the tool's frame ``k``. A point whose confidence is NaN was not found.

Confidences must lie in [0, 1] (OpenPose's do); pixels of found points must be finite.

Conversion to the sequence
--------------------------
Another tool sees the videos at full resolution, counted from their first frame: pixel ``u`` becomes
``(u + 0.5) / F - 0.5`` with ``F`` the sequence's ``downscale`` (``meta.json``, default 1; pixel centres are the
coordinates, as in :func:`data_tools.vision.video.fitted_camera`), and the tool's frame ``k`` is the sequence's frame
``k - first_video_frame`` (``meta.json``, default 0). Frames outside the sequence are dropped; sequence frames
no file covers, and cameras no source names, have confidence 0.

Cameras: sources in the sequence's camera order (``cameras.json``), as many views as it has cameras, or every
source named ``CAMERA=PATH`` (cameras not named get no keypoints). An ``.npz`` with ``cameras`` names its
views itself.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from data_tools.io.checks import MAX_PRINCIPAL_PX, load_npz, real_number
from data_tools.io.textfiles import read_json
from data_tools.sequences.keypoint_file import SequenceKeypoints, write_keypoints
from data_tools.sequences.sequence import OWN, read_sequence
from data_tools.vision.keypoints.layouts import LAYOUT_NAMES, LAYOUTS, layout_index, to_canonical
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINTS

#: Detector names recorded in the keypoint file's ``source``.
OPENPOSE_JSON, ARRAY = "openpose-json", "array"
#: Pixel coordinates beyond this (either sign) are garbage, not a point off the image.
MAX_PIXEL = MAX_PRINCIPAL_PX
#: A camera whose found points lie outside its images more often than this is refused: they are pixels of
#: another resolution, another camera or another frame numbering.
MAX_OUTSIDE_SHARE = 0.5
_ARRAY_SUFFIXES = (".npy", ".npz")


@dataclass
class ViewDetections:
    """One camera's detections as a tool wrote them: ``points`` ``N x J x 3`` (full-resolution pixels ``x, y``
    and a confidence in [0, 1]; NaN pixels where not found) of the tool's frames ``frames`` ``(N,)``, in
    ``layout``. ``camera`` is the camera's name where the source says it, ``path`` the folder or file read,
    ``files`` how many files were read and ``version`` what they say of the tool's version (None if nothing)."""

    camera: str | None
    frames: np.ndarray
    points: np.ndarray
    layout: str
    path: Path
    files: int = 1
    version: Any = None


# ---------------------------------------------------------------------------
# Layouts
# ---------------------------------------------------------------------------

def layout_for_count(count: int, layout: str | None, path: str | Path) -> str:
    """The layout of detections of ``count`` points: ``layout`` when given (its length must be ``count``), else
    the one layout that has ``count`` points; an :class:`InputError` naming ``path`` otherwise."""
    if layout is not None:
        if layout not in LAYOUTS:
            raise InputError(f"unknown keypoint layout {layout!r} (known: {', '.join(LAYOUTS)})", path)
        if count != len(LAYOUT_NAMES[layout]):
            raise InputError(f"{count} points per person, but the {layout} layout has {len(LAYOUT_NAMES[layout])}",
                             path)
        return layout
    fits = [name for name, names in LAYOUT_NAMES.items() if len(names) == count]
    if len(fits) > 1:
        raise InputError(f"{count} points per person may be {' or '.join(fits)}: give the layout", path)
    if not fits:
        known = ", ".join(f"{len(n)} {name}" for name, n in LAYOUT_NAMES.items())
        raise InputError(f"{count} points per person match no known layout ({known})", path)
    return fits[0]


def check_points(points: np.ndarray, path: str | Path, where: str = "") -> np.ndarray:
    """Detections ``(..., J, 3)`` checked: confidences in [0, 1] (NaN: not found), pixels of found points finite
    and within :data:`MAX_PIXEL`. Returns them as float with NaN pixels and confidence 0 where not found."""
    points = np.array(points, dtype=float)
    conf = points[..., 2]
    bad = ~np.isnan(conf) & ~((conf >= 0) & (conf <= 1))
    if bad.any():
        at = np.argwhere(bad)[0]
        raise InputError(f"{where}confidence {conf[tuple(at)]:g} of point {at[-1]}{_frame_text(at)} is outside "
                         "[0, 1]", path)
    found = conf > 0
    xy = points[..., :2]
    bad = found & ~(np.isfinite(xy) & (np.abs(xy) <= MAX_PIXEL)).all(axis=-1)
    if bad.any():
        at = np.argwhere(bad)[0]
        raise InputError(f"{where}point {at[-1]}{_frame_text(at)} has confidence {conf[tuple(at)]:g} but pixel "
                         f"{tuple(float(v) for v in xy[tuple(at)])}: expected finite numbers within ±{MAX_PIXEL:g}",
                         path)
    points[~found] = (np.nan, np.nan, 0.0)
    return points


def _frame_text(index: np.ndarray) -> str:
    """`` in row k`` (`` view v``) for an index into a ``(T, [V,] J)`` array; nothing for one frame."""
    if len(index) == 1:
        return ""
    return f" in row {index[0]}" + (f", view {index[1]}" if len(index) == 3 else "")


# ---------------------------------------------------------------------------
# OpenPose JSON
# ---------------------------------------------------------------------------

def _numbers(values: Any, path: Path, person: int) -> np.ndarray:
    """``pose_keypoints_2d`` of person ``person`` as floats; anything but a flat list of numbers is refused."""
    if not isinstance(values, list):
        raise InputError(f"people[{person}].pose_keypoints_2d is not a list of numbers", path)
    for i, v in enumerate(values):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"people[{person}].pose_keypoints_2d[{i}] is not a number: {json.dumps(v)[:30]}",
                             path)
    if len(values) % 3:
        raise InputError(f"people[{person}].pose_keypoints_2d has {len(values)} numbers, not 3 per point "
                         "(x, y, confidence)", path)
    try:
        return np.array(values, dtype=float).reshape(-1, 3)
    except OverflowError:
        raise InputError(f"people[{person}].pose_keypoints_2d holds a number beyond the float range", path) from None


def read_openpose_frame(path: str | Path, layout: str | None = None) -> tuple[np.ndarray | None, str | None, Any]:
    """One OpenPose-style JSON file: the detection ``J x 3`` of the person with the largest summed confidence
    (None when ``people`` is empty), its layout (``layout`` or inferred; None with nobody) and the file's
    ``version`` (None if absent). Any problem is one :class:`InputError` naming the file."""
    path = Path(path)
    doc = read_json(path, "the keypoints file")
    if not isinstance(doc, dict) or not isinstance(doc.get("people"), list):
        raise InputError("not an OpenPose keypoints file: no 'people' list", path)
    best, best_score = None, -1.0
    for i, person in enumerate(doc["people"]):
        if not isinstance(person, dict) or "pose_keypoints_2d" not in person:
            raise InputError(f"people[{i}] is not an object with pose_keypoints_2d", path)
        values = _numbers(person["pose_keypoints_2d"], path, i)
        if not len(values):  # a person listed without body points
            continue
        layout = layout_for_count(len(values), layout, path)
        values = check_points(values, path, f"people[{i}]: ")
        score = float(values[:, 2].sum())
        if score > best_score:
            best, best_score = values, score
    version = doc.get("version")
    if version is not None and not isinstance(version, (int, float, str)):
        version = None
    return best, (layout if best is not None else None), version


def _frame_number(path: Path) -> int:
    numbers = re.findall(r"\d+", path.stem)
    if not numbers:
        raise InputError("a keypoints file's name must hold its frame number (e.g. name_000000000012_keypoints"
                         ".json)", path)
    return int(numbers[-1])


def openpose_files(folder: str | Path) -> dict[int, Path]:
    """The JSON files of ``folder`` by frame number (the last number in each name); a missing or empty folder,
    or two files of one frame, is an :class:`InputError`."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("keypoint folder does not exist" if not folder.exists() else
                         "not a folder of OpenPose JSON files (or an .npy/.npz array)", folder)
    files: dict[int, Path] = {}
    for path in sorted(p for p in folder.iterdir() if p.suffix.lower() == ".json" and p.is_file()):
        k = _frame_number(path)
        if k in files:
            raise InputError(f"two files of frame {k}: {files[k].name} and {path.name}", folder)
        files[k] = path
    if not files:
        raise InputError("no .json keypoint files in the folder", folder)
    return files


def read_openpose_folder(folder: str | Path, layout: str | None = None, frames: range | None = None,
                         camera: str | None = None) -> ViewDetections:
    """One camera's OpenPose-style JSON files in ``folder``: every frame, or only the tool's frames in
    ``frames``. All files must share one layout (``layout`` or the first inferred)."""
    folder = Path(folder)
    files = openpose_files(folder)
    chosen = sorted(k for k in files if frames is None or k in frames)
    if not chosen:
        raise InputError(f"no file of the sequence's video frames {frames.start} to {frames.stop - 1}: the files "
                         f"are of frames {min(files)} to {max(files)} (a tool's frame k is the sequence's frame k - "
                         "first_video_frame)", folder)
    points = np.full((len(chosen), 0, 3), np.nan)
    rows, versions = [], []
    found_layout = layout
    for k in chosen:
        det, det_layout, version = read_openpose_frame(files[k], found_layout)
        found_layout = found_layout or det_layout
        rows.append(det)
        if version is not None and version not in versions:
            versions.append(version)
    if found_layout is not None:
        J = len(LAYOUT_NAMES[found_layout])
        empty = np.zeros((J, 3))
        empty[:, :2] = np.nan
        points = np.stack([empty if r is None else r for r in rows]) if rows else np.zeros((0, J, 3))
    return ViewDetections(camera, np.array(chosen, dtype=int), points, found_layout or "", folder, len(chosen),
                          versions[0] if len(versions) == 1 else (versions or None))


# ---------------------------------------------------------------------------
# Arrays
# ---------------------------------------------------------------------------

def _load_npy(path: Path) -> np.ndarray:
    try:
        with open(path, "rb") as f:
            return np.load(f, allow_pickle=False)
    except OSError as exc:
        raise InputError(f"cannot read the keypoint array: {exc.strerror or exc}", path) from None
    except Exception as exc:  # noqa: BLE001 -- numpy.lib.format fails in many undocumented ways
        reason = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read the keypoint array: not an intact .npy file ({reason})", path) from None


def _text_array(value: np.ndarray, what: str, path: Path) -> list[str]:
    if value.dtype.kind not in "US":
        raise InputError(f"the array file's {what} must be text, got {value.dtype}", path)
    return [str(v) for v in np.atleast_1d(value).tolist()]


def read_keypoint_array(path: str | Path, layout: str | None = None) -> list[ViewDetections]:
    """An array file's detections, one :class:`ViewDetections` per view (named where an ``.npz`` has
    ``cameras``); row ``k`` is the tool's frame ``k``."""
    path = Path(path)
    names = None
    if path.suffix.lower() == ".npz":
        arrays = load_npz(path, "the keypoint array file", ("points",))
        points = arrays["points"]
        if "layout" in arrays:
            (file_layout,) = _text_array(arrays["layout"], "layout", path)[:1] or [None]
            if layout is not None and file_layout != layout:
                raise InputError(f"the file's layout is {file_layout!r}, not {layout!r} as given", path)
            layout = file_layout
        if "cameras" in arrays:
            names = _text_array(arrays["cameras"], "cameras", path)
    else:
        points = _load_npy(path)
    if points.dtype.kind not in "iuf":
        raise InputError(f"the keypoints must be numbers, got an array of {points.dtype}", path)
    if points.ndim not in (3, 4) or points.shape[-1] != 3:
        raise InputError(f"the keypoints must be T x V x J x 3 (or T x J x 3 for one camera): x, y, confidence; "
                         f"got shape {points.shape}", path)
    if points.ndim == 3:
        points = points[:, None]
    layout = layout_for_count(points.shape[2], layout, path)
    if names is not None and len(names) != points.shape[1]:
        raise InputError(f"the file names {len(names)} cameras but its points have {points.shape[1]} views", path)
    points = check_points(points, path)
    frames = np.arange(points.shape[0])
    return [ViewDetections(None if names is None else names[v], frames, points[:, v], layout, path)
            for v in range(points.shape[1])]


# ---------------------------------------------------------------------------
# Sources, cameras and the sequence
# ---------------------------------------------------------------------------

def parse_sources(sources: Iterable[str | Path] | Mapping[str, str | Path]) -> list[tuple[str | None, Path]]:
    """``(camera or None, path)`` of each source: paths, ``CAMERA=PATH`` texts or a mapping camera -> path."""
    if isinstance(sources, Mapping):
        return [(str(cam), Path(p)) for cam, p in sources.items()]
    if isinstance(sources, (str, Path)):
        sources = [sources]
    out: list[tuple[str | None, Path]] = []
    for item in sources:
        text = str(item)
        cam, sep, rest = text.partition("=")
        if isinstance(item, str) and sep and cam.strip() and not Path(text).exists():
            out.append((cam.strip(), Path(rest.strip())))
        else:
            out.append((None, Path(item)))
    if not out:
        raise InputError("no keypoint source given")
    return out


def _read_source(camera: str | None, path: Path, layout: str | None, frames: range) -> list[ViewDetections]:
    if path.suffix.lower() in _ARRAY_SUFFIXES and not path.is_dir():
        if not path.exists():
            raise InputError("keypoint array file does not exist", path)
        views = read_keypoint_array(path, layout)
        if camera is not None:
            if len(views) != 1 or views[0].camera not in (None, camera):
                got = f"cameras {', '.join(str(v.camera) for v in views)}" if views[0].camera else f"{len(views)} views"
                raise InputError(f"given for camera {camera!r} but the file holds {got}", path)
            views[0].camera = camera
        return views
    view = read_openpose_folder(path, layout, frames)
    view.camera = camera
    return [view]


def _assign(views: list[ViewDetections], cameras: tuple[str, ...], seq_root: Path) -> list[ViewDetections | None]:
    """The detections of each of the sequence's ``cameras`` (None where no source names one)."""
    named = [v.camera is not None for v in views]
    if any(named) and not all(named):
        raise InputError("give every keypoint source as CAMERA=PATH, or none (then they follow the sequence's "
                         f"camera order: {', '.join(cameras)})")
    if not any(named):
        if len(views) != len(cameras):
            raise InputError(f"the keypoint sources give {len(views)} view(s) but the sequence has "
                             f"{len(cameras)} cameras ({', '.join(cameras)}): one folder per camera in that "
                             "order, or CAMERA=PATH pairs", seq_root / "cameras.json")
        return list(views)
    out: list[ViewDetections | None] = [None] * len(cameras)
    for v in views:
        if v.camera not in cameras:
            raise InputError(f"keypoints of camera {v.camera!r}, which the sequence lacks (its cameras: "
                             f"{', '.join(cameras)})", v.path)
        i = cameras.index(v.camera)
        if out[i] is not None:
            raise InputError(f"two keypoint sources for camera {v.camera!r}: {out[i].path} and {v.path}")
        out[i] = v
    return out


def check_keypoint_layout(seq) -> None:
    """Refuse a sequence (:class:`~data_tools.sequences.sequence.Sequence`) whose layout does not read keypoints: only
    this toolkit's own layout has ``keypoints/keypoints.npz`` (a PARSEC bodytrack folder's is never read)."""
    if seq.layout != OWN:
        raise InputError(f"keypoints are read from sequence folders of this toolkit's layout only, not {seq.layout}",
                         seq.root)


def sequence_placement(meta: Mapping, meta_path: Path) -> tuple[float, int]:
    """``downscale`` (>= 1) and ``first_video_frame`` (>= 0) of a sequence's ``meta.json`` (1 and 0 if absent)."""
    downscale = real_number(meta.get("downscale", 1.0), "downscale", meta_path, lo=1.0, hi=64.0)
    first = meta.get("first_video_frame", 0)
    if isinstance(first, bool) or not isinstance(first, int) or first < 0:
        raise InputError(f"first_video_frame must be a whole number >= 0, got {json.dumps(first)[:30]}", meta_path)
    return downscale, first


def to_sequence_pixels(points: np.ndarray, downscale: float) -> np.ndarray:
    """Full-resolution detections ``(..., 3)`` in the pixels of images shrunk by ``downscale``:
    ``u -> (u + 0.5) / F - 0.5`` for x and y; confidences unchanged."""
    out = np.array(points, dtype=float)
    out[..., :2] = (out[..., :2] + 0.5) / downscale - 0.5
    return out


def _check_inside(points: np.ndarray, rig, views: list[ViewDetections | None]) -> None:
    """Refuse a camera whose found points ``T x K x 3`` mostly lie outside its images."""
    for v, view in enumerate(views):
        if view is None:
            continue
        cam = rig[v]
        p = points[:, v]
        found = p[..., 2] > 0
        if not found.any():
            continue
        x, y = p[..., 0][found], p[..., 1][found]
        outside = (x < -0.5) | (x > cam.width - 0.5) | (y < -0.5) | (y > cam.height - 0.5)
        if outside.mean() > MAX_OUTSIDE_SHARE:
            raise InputError(f"{outside.sum()} of the {found.sum()} keypoints found in camera {cam.name!r} lie "
                             f"outside its {cam.width} x {cam.height} images: they are read as pixels of the "
                             "full-resolution video, shrunk by meta.json's downscale (another resolution, camera "
                             "or frame numbering?)", view.path)


def _placed_points(views: list[ViewDetections | None], n_frames: int, first: int,
                   downscale: float) -> np.ndarray:
    """The body keypoints ``T x V x K x 3`` of the sequence's ``n_frames`` frames (from video frame ``first``) in
    its pixels (images shrunk by ``downscale``); NaN pixels and confidence 0 where nothing covers a frame."""
    points = np.full((n_frames, len(views), len(KEYPOINTS), 3), np.nan)
    points[..., 2] = 0.0
    for v, view in enumerate(views):
        if view is None or not view.layout:
            continue
        keep = (view.frames >= first) & (view.frames < first + n_frames)
        if not keep.any():
            raise InputError(f"no row of the sequence's video frames {first} to {first + n_frames - 1}: the "
                             f"file has {len(view.frames)} rows (row k is video frame k)", view.path)
        canonical = to_canonical(to_sequence_pixels(view.points[keep], downscale), view.layout)
        points[view.frames[keep] - first, v] = canonical
    return points


def import_keypoints(seq_root: str | Path, sources: Iterable[str | Path] | Mapping[str, str | Path],
                     layout: str | None = None, *, write: bool = True) -> SequenceKeypoints:
    """Read another tool's keypoints for the sequence in ``seq_root`` and write them to its
    ``keypoints/keypoints.npz`` (unless ``write`` is False).

    ``sources``: OpenPose-style JSON folders and ``.npy``/``.npz`` arrays, in the sequence's camera order or as
    ``CAMERA=PATH`` texts (or a mapping camera -> path); ``layout``: the detector's layout (see the module; needed
    for 25 points). Returns ``points`` ``T x V x K x 3`` in the sequence's frames, cameras and pixels. Any
    problem is one :class:`InputError` naming the file.
    """
    if layout is not None and layout not in LAYOUTS:
        raise InputError(f"unknown keypoint layout {layout!r} (known: {', '.join(LAYOUTS)})")
    seq = read_sequence(seq_root, keypoints=False)  # the file this replaces may be broken or of other cameras
    check_keypoint_layout(seq)
    downscale, first = sequence_placement(seq.meta, seq.root / "meta.json")
    frames = range(first, first + seq.n_frames)
    views: list[ViewDetections] = []
    for camera, path in parse_sources(sources):
        views += _read_source(camera, path, layout, frames)
    layouts = sorted({v.layout for v in views if v.layout})
    if len(layouts) > 1:
        raise InputError(f"the keypoint sources are of different layouts ({', '.join(layouts)}): import one "
                         "layout at a time")
    placed = _assign(views, seq.rig.names, seq.root)
    points = _placed_points(placed, seq.n_frames, first, downscale)
    if not (points[..., 2] > 0).any():
        raise InputError(f"nobody found in any source's files of the sequence's video frames {first} to "
                         f"{first + seq.n_frames - 1}", views[0].path)
    _check_inside(points, seq.rig, placed)
    result = SequenceKeypoints(points, seq.rig.names, _source(views, layouts[0], downscale, first))
    if write:
        write_keypoints(seq.root, result)
    return result


def found_share(keypoints: SequenceKeypoints) -> float:
    """The share of keypoints found (confidence > 0) over every frame and view, counting only the body keypoints
    that the source's layout has (every one where it names no known layout)."""
    layout = keypoints.source.get("layout")
    have = layout_index(layout) >= 0 if layout in LAYOUTS else np.ones(len(KEYPOINTS), bool)
    conf = keypoints.confidence[..., have]
    return float((conf > 0).mean()) if conf.size else 0.0


def _source(views: list[ViewDetections], layout: str, downscale: float, first: int) -> dict:
    """The ``source`` record of imported keypoints: detector, version, layout and the files read."""
    json_views = [v for v in views if v.path.is_dir()]
    detector = OPENPOSE_JSON if len(json_views) == len(views) else ARRAY if not json_views else \
        f"{OPENPOSE_JSON}+{ARRAY}"
    versions = []
    for v in views:
        for value in v.version if isinstance(v.version, list) else [v.version]:
            if value is not None and value not in versions:
                versions.append(value)
    files = [{"camera": v.camera, "path": str(v.path.resolve()), "files": v.files,
              "frames": [int(v.frames.min()), int(v.frames.max())] if len(v.frames) else []} for v in views]
    source = {"detector": detector, "version": versions[0] if len(versions) == 1 else (versions or None),
              "layout": layout, "files": files, "downscale": downscale, "first_video_frame": first}
    if json_views:
        source["people"] = "of several, the one with the largest summed confidence, frame by frame"
    return source

