"""Multi-view sequences on disk: the project's own layout (reader and writer) and PARSEC bodytrack's (reader).

Own layout (docs/reference/file_formats.md)::

    DIR/cameras.json                      the rig (tracker.core.cameras)
    DIR/images/<camera>/000000.png ...    one image per frame and camera
    DIR/background/<camera>.png           background plate, where there is one
    DIR/masks/<camera>/000000.png ...     foreground masks (non-zero = person), instead of background plates
    DIR/keypoints/keypoints.npz           2-D keypoints of every frame and camera (data_tools.sequences.keypoint_file)
    DIR/groundtruth.npz                   poses T x D, markers T x 15 x 3 (mm), fps -- when known
    DIR/meta.json                         source, subject, fps, body shape, generator settings

PARSEC bodytrack layout (read as it is)::

    DIR/CALIB/Camera1.cal ...  DIR/CAM1/image0000.bmp ...  DIR/FG1/image0000.bmp ...
    DIR/BodyShapeParameters.txt  DIR/InitialPose.txt  [DIR/PoseParameters.txt]

:func:`read_sequence` recognises either and returns a :class:`Sequence`. Images
come back from :class:`Sequence` as ``H x W x 3`` RGB uint8 (greyscale files
are converted, so frames and background plates always match); masks as
``H x W`` bool. Every problem (missing folder or frame, wrong image size,
unreadable, truncated or non-image file, empty mask, implausible values in the
ground truth or ``meta.json``) raises one :class:`InputError` naming the file,
with nothing printed before it.
"""
from __future__ import annotations

import json
import os
import re
import struct
import sys
import threading
import zlib
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from data_tools.io.checks import MAX_FPS, body_shape, checked_motion, load_npz, real_number
from data_tools.io.textfiles import read_json
from data_tools.sequences.calibration import read_bodytrack_calibration, read_cameras_json, write_cameras_json
from data_tools.sequences.keypoint_file import SequenceKeypoints, read_keypoints
from tracker.core.body import BodyModel, fifteen_cone_model
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError
from tracker.engine.likelihood import Frame

OWN, BODYTRACK = "own", "bodytrack"


@dataclass
class GroundTruth:
    """Known poses ``T x D`` and markers ``T x 15 x 3`` (mm) of a sequence, at ``fps`` Hz."""

    poses: np.ndarray
    markers: np.ndarray
    fps: float


@dataclass
class Sequence:
    """A readable multi-view sequence (either layout).

    ``image_paths[v][k]`` is frame ``k`` of camera ``v``; ``background_paths[v]``
    and ``mask_paths[v][k]`` are ``None`` where the layout has none.
    ``initial_poses`` ``n x D`` are poses known at the start (the ground truth's
    for our layout, ``InitialPose.txt`` for bodytrack).
    """

    root: Path
    layout: str
    rig: CameraRig
    model: BodyModel
    image_paths: list[list[Path]]
    background_paths: list[Path | None]
    mask_paths: list[list[Path]] | None
    groundtruth: GroundTruth | None
    initial_poses: np.ndarray | None
    fps: float | None
    meta: dict = field(default_factory=dict)
    diffusion_std: np.ndarray | None = None
    keypoints: SequenceKeypoints | None = None
    _plates: dict = field(default_factory=dict, repr=False)

    @property
    def n_frames(self) -> int:
        return len(self.image_paths[0])

    @property
    def n_views(self) -> int:
        return len(self.rig)

    def check_frame(self, frame: int) -> int:
        if not 0 <= frame < self.n_frames:
            raise InputError(f"frame {frame} out of range: the sequence has {self.n_frames} frames "
                             f"(0..{self.n_frames - 1})", self.root)
        return frame

    def image(self, frame: int, view: int) -> np.ndarray:
        """Frame ``frame`` of camera ``view``: ``H x W x 3`` RGB uint8 (a greyscale file is converted)."""
        self.check_frame(frame)
        return read_image(self.image_paths[view][frame], self.rig[view].width, self.rig[view].height, rgb=True)

    def background(self, view: int) -> np.ndarray | None:
        """The background plate of camera ``view`` as ``H x W x 3`` RGB (read once, then kept), or None."""
        path = self.background_paths[view]
        if path is None:
            return None
        if view not in self._plates:
            self._plates[view] = read_image(path, self.rig[view].width, self.rig[view].height, rgb=True)
        return self._plates[view]

    def mask(self, frame: int, view: int) -> np.ndarray | None:
        """The provided foreground mask (bool ``H x W``), or None when the layout has none."""
        if self.mask_paths is None:
            return None
        self.check_frame(frame)
        return read_mask(self.mask_paths[view][frame], self.rig[view].width, self.rig[view].height)

    def frame(self, frame: int, views) -> Frame:
        """Frame ``frame`` in the cameras ``views`` as the likelihood sees it: images, with the provided masks
        where the layout has them, else the background plates (one of the two is needed)."""
        views = list(views)
        images = tuple(self.image(frame, v) for v in views)
        keypoints = None if self.keypoints is None else self.keypoints.points[frame, views]
        if self.mask_paths is not None:
            return Frame(frame, images, masks=tuple(self.mask(frame, v) for v in views), keypoints=keypoints)
        plates = [self.background(v) for v in views]
        missing = [self.rig[v].name for v, b in zip(views, plates) if b is None]
        if missing and keypoints is None:
            raise InputError(f"no background plate and no masks for camera(s) {', '.join(missing)}", self.root)
        return Frame(frame, images, backgrounds=None if missing else tuple(plates), keypoints=keypoints)


# ---------------------------------------------------------------------------
# Images
# ---------------------------------------------------------------------------

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_header(data: bytes, path: Path) -> tuple[int, int, int, int]:
    """(width, height, bit depth, colour type) of a PNG after checking its chunk structure and every CRC, so
    that the decoder only ever sees intact files (colour type 0 is grey, 4 grey with alpha)."""
    pos, header, chunks = len(_PNG_SIGNATURE), None, set()
    while pos + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        end = pos + 12 + length
        if end > len(data):
            break
        if zlib.crc32(data[pos + 4:end - 4]) != struct.unpack(">I", data[end - 4:end])[0]:
            raise InputError(f"cannot read image: corrupt PNG (CRC error in a {kind[:4]!r} chunk)", path)
        if kind == b"IHDR" and length >= 10:
            header = struct.unpack(">IIBB", data[pos + 8:pos + 18])
        chunks.add(kind)
        if kind == b"IEND":
            break
        pos = end
    if header is None or b"IEND" not in chunks or b"IDAT" not in chunks:
        raise InputError("cannot read image: truncated or corrupt PNG (header, data or end chunk missing)", path)
    return header


def _bmp_size(data: bytes, path: Path) -> tuple[int, int]:
    """(width, height) from a BMP header (BITMAPCOREHEADER or later)."""
    if len(data) < 26:
        raise InputError("cannot read image: truncated BMP header", path)
    if struct.unpack("<I", data[14:18])[0] == 12:
        return struct.unpack("<HH", data[18:22])
    width, height = struct.unpack("<ii", data[18:26])
    return width, abs(height)


_STDERR_LOCK = threading.Lock()


@contextmanager
def _stderr_silenced():
    """Point file descriptor 2 at the null device for the duration (a no-op if it cannot be duplicated).

    libpng writes its warnings and errors straight to the C stderr, and OpenCV
    logs there too; neither heeds OpenCV's log level, so a corrupt image would
    print library messages before our one-line error (libpng does so even for
    a PNG whose checksums pass but whose compressed data is corrupt, so
    checking the CRCs first is not enough). The lock keeps concurrent
    decodes from restoring each other's descriptors, which also serialises
    the decodes of ``--threads`` > 2's extra prefetch threads; output of
    other threads during a decode (about 6 ms per 640x480 PNG, 25 ms of each
    four-view frame) is lost.
    """
    with _STDERR_LOCK:
        try:
            sys.stderr.flush()
            saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
        except (OSError, ValueError):
            yield
            return
        try:
            os.dup2(null, 2)
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            os.close(null)


def _decode(data: bytes, grey: bool) -> np.ndarray | None:
    """A PNG's or BMP's pixels, ``H x W`` grey if ``grey`` (any alpha dropped) or ``H x W x 3`` RGB (alpha
    dropped, palettes expanded); None if decoding fails.

    ``cv2.imdecode`` with library messages on stderr suppressed. OpenCV releases
    the GIL while it decodes, so the filter's background thread keeps running
    while the calling thread decodes the next frame; libspng's Python binding
    (``pyspng``, tried and measured) decodes a PNG in 20-30% less time alone
    but holds the GIL, which made annealed CRBM tracking about a tenth slower
    end to end (docs/reference/performance.md, "Tried and not kept").
    """
    with _stderr_silenced():
        try:
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error:  # e.g. more pixels than OpenCV allows
            return None
    if img is None or img.ndim == 2:
        return img
    if grey or img.shape[2] < 3:  # OpenCV gives grey + alpha as 2 or 4 channels, by version
        return img[..., 0].copy()
    return cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2RGB)


def read_image(path: Path, width: int, height: int, rgb: bool = False) -> np.ndarray:
    """Read an image file and check its size against the camera's (``width`` x ``height`` pixels).

    PNG and BMP only. Returns ``H x W x 3`` RGB or ``H x W`` grey uint8 (an
    alpha channel is dropped); ``rgb`` converts grey to RGB. Headers (and PNG
    checksums) are checked before decoding, so a file claiming a huge size is
    refused without allocating it and a broken file is one :class:`InputError`,
    with no library warnings printed.
    """
    path = Path(path)
    try:
        n_bytes = path.stat().st_size
        if n_bytes > 8 * width * height + (1 << 20):  # more than any width x height image file needs
            raise InputError(f"image file is {n_bytes} bytes: too large for a {width}x{height} image", path)
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError("image file is missing", path) from None
    except OSError as exc:
        raise InputError(f"cannot read image: {exc.strerror or exc}", path) from None
    if data.startswith(_PNG_SIGNATURE):
        *size, depth, colour_type = _png_header(data, path)
        grey = colour_type in (0, 4)
    elif data.startswith(b"BM"):
        size, depth, grey = _bmp_size(data, path), 8, False
    else:  # other formats are not checked before decoding, so not decoded at all
        raise InputError("cannot read image: not a PNG or BMP file (the formats of both sequence layouts)", path)
    if tuple(size) != (width, height):
        raise InputError(f"image is {size[0]}x{size[1]} pixels but its camera is {width}x{height}", path)
    if depth > 8:
        raise InputError(f"expected an 8-bit image, got {depth} bits per sample", path)
    img = _decode(data, grey)
    if img is None:
        raise InputError("cannot read image (unsupported, truncated or corrupt file)", path)
    if img.dtype != np.uint8:
        raise InputError(f"expected an 8-bit image, got {img.dtype}", path)
    if img.shape[:2] != (height, width):
        raise InputError(f"image is {img.shape[1]}x{img.shape[0]} pixels but its camera is {width}x{height}", path)
    if img.ndim == 3 and img.shape[2] != 3:
        raise InputError(f"expected 1 to 4 channels, got {img.shape[2]}", path)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2RGB) if rgb and img.ndim == 2 else img


def read_mask(path: Path, width: int, height: int) -> np.ndarray:
    """A foreground mask (non-zero = person) as bool ``H x W``; an all-zero mask is refused."""
    img = read_image(path, width, height)
    mask = img > 0 if img.ndim == 2 else np.any(img > 0, axis=2)
    if not mask.any():
        raise InputError("foreground mask is all zero (no person)", path)
    return mask


def write_image(path: Path, image: np.ndarray) -> None:
    """Write ``H x W`` grey or ``H x W x 3`` RGB uint8 as a PNG. Encoded in memory and written by Python, so a
    failed write is an :class:`OSError` naming its cause (OpenCV's own writer only returns False).

    zlib's Huffman-only strategy: on rendered frames with sensor noise it gives smaller files than compression
    level 1 (482 against 541 kB for 640 x 480 RGB), encodes 2.7 times and decodes 1.5 times as fast (4.4
    against 6.8 ms, the largest part of reading a frame)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, encoded = cv2.imencode(".png", data, [cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY])
    if not ok:
        raise InputError("cannot encode image", path)
    Path(path).write_bytes(encoded.tobytes())


# ---------------------------------------------------------------------------
# Own layout
# ---------------------------------------------------------------------------

FRAME_NAME = "{:06d}.png"


def frame_path(root: Path, camera: str, frame: int) -> Path:
    return Path(root) / "images" / camera / FRAME_NAME.format(frame)


def _camera_frames(folder: Path, label: str, pattern: str, name_format: str,
                   first: tuple[int, str] | None) -> list[Path]:
    """The frame files ``0..n-1`` of one camera folder (file names matching ``pattern``, numbered by its group).

    ``first`` is (frame count, name) of the first camera, which this one must match.
    """
    if not folder.is_dir():
        raise InputError(f"{label} is missing", folder)
    rx = re.compile(pattern)
    numbers = sorted(int(m.group(1)) for p in folder.iterdir() if (m := rx.fullmatch(p.name)))
    if not numbers:
        raise InputError("no frames found", folder)
    for expected, got in enumerate(numbers):
        if expected != got:
            raise InputError(f"frame {expected} is missing (expected {name_format.format(expected)})", folder)
    if first is not None and len(numbers) != first[0]:
        raise InputError(f"{folder.name} has {len(numbers)} frames but {first[1]} has {first[0]}", folder)
    return [folder / name_format.format(k) for k in range(len(numbers))]


def write_groundtruth(root: Path, poses: np.ndarray, markers: np.ndarray, fps: float) -> None:
    np.savez(Path(root) / "groundtruth.npz", poses=np.asarray(poses, float), markers=np.asarray(markers, float),
             fps=float(fps))


def read_groundtruth(path: Path, n_dofs: int) -> GroundTruth:
    """``groundtruth.npz``: poses ``T x n_dofs``, markers ``T x 15 x 3`` (mm) and fps, each checked."""
    arrays = load_npz(path, "ground truth", ("poses", "markers", "fps"))
    poses, (markers,), fps = checked_motion(arrays, path, n_dofs)
    return GroundTruth(poses, markers, fps)


def write_meta(root: Path, meta: dict) -> None:
    (Path(root) / "meta.json").write_text(json.dumps(meta, indent=1, sort_keys=True))


def write_sequence_header(root: Path, rig: CameraRig, meta: dict) -> None:
    """Create ``root`` with ``cameras.json`` and ``meta.json`` (frames are written one by one)."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    write_cameras_json(rig, root / "cameras.json")
    write_meta(root, meta)


def _read_own(root: Path, keypoints: bool = True) -> Sequence:
    rig = read_cameras_json(root / "cameras.json")
    meta_path = root / "meta.json"
    meta = read_json(meta_path, "meta.json") if meta_path.exists() else {}
    if not isinstance(meta, dict):
        raise InputError("expected a JSON object", meta_path)
    shape = meta.get("body_shape")
    model = fifteen_cone_model(None if shape is None else body_shape(shape, meta_path))
    meta_fps = meta.get("fps")
    if meta_fps is not None:
        meta_fps = real_number(meta_fps, "fps", meta_path, hi=MAX_FPS, positive=True, unit=" Hz")
    image_paths, backgrounds = [], []
    if (root / "images").is_dir():
        stray = sorted(d.name for d in (root / "images").iterdir()
                       if d.is_dir() and not d.name.startswith(".") and d.name not in rig.names
                       and any(f.suffix.lower() == ".png" for f in d.iterdir()))
        if stray:
            raise InputError(f"images/{stray[0]}/ has images but cameras.json has no camera {stray[0]!r} "
                             f"(its cameras: {', '.join(rig.names)})", root / "cameras.json")
    for cam in rig.cameras:
        first = (len(image_paths[0]), rig.names[0]) if image_paths else None
        image_paths.append(_camera_frames(root / "images" / cam.name, f"camera folder for {cam.name!r}",
                                          r"(\d{6})\.png", FRAME_NAME, first))
        bg = root / "background" / f"{cam.name}.png"
        backgrounds.append(bg if bg.exists() else None)
    mask_paths = None
    if (root / "masks").is_dir():  # silhouettes of one's own, instead of background plates
        mask_paths = [_camera_frames(root / "masks" / cam.name, f"mask folder for {cam.name!r}", r"(\d{6})\.png",
                                     FRAME_NAME, (len(image_paths[0]), rig.names[0])) for cam in rig.cameras]
    gt = None
    if (root / "groundtruth.npz").exists():
        gt = read_groundtruth(root / "groundtruth.npz", model.n_dofs)
        if len(gt.poses) != len(image_paths[0]):
            raise InputError(f"ground truth has {len(gt.poses)} frames but the images have {len(image_paths[0])}",
                             root / "groundtruth.npz")
    fps = gt.fps if gt else meta_fps
    seq = Sequence(root=root, layout=OWN, rig=rig, model=model, image_paths=image_paths,
                   background_paths=backgrounds, mask_paths=mask_paths, groundtruth=gt,
                   initial_poses=None if gt is None else gt.poses, fps=fps, meta=meta,
                   keypoints=read_keypoints(root, rig.names, len(image_paths[0])) if keypoints else None)
    for v in range(len(rig)):  # fail early on a wrong-sized or unreadable first frame or plate (kept once read)
        seq.image(0, v)
        seq.background(v)
    return seq


# ---------------------------------------------------------------------------
# PARSEC bodytrack layout
# ---------------------------------------------------------------------------

BODYTRACK_FRAME = "image{:04d}.bmp"


def _read_bodytrack(root: Path, width: int = 640, height: int = 480) -> Sequence:
    from data_tools.sequences.bodytrack import bodytrack_model, read_poses

    cal_files = [root / "CALIB" / f"Camera{k}.cal" for k in _bodytrack_cameras(root)]
    rig = CameraRig([read_bodytrack_calibration(p, f"CAM{i + 1}", width, height) for i, p in enumerate(cal_files)])
    model, params = bodytrack_model(root)
    image_paths, mask_paths = [], []
    for i in range(len(cal_files)):
        for prefix, lists in (("CAM", image_paths), ("FG", mask_paths)):
            first = (len(image_paths[0]), "CAM1") if image_paths else None
            lists.append(_camera_frames(root / f"{prefix}{i + 1}", f"camera folder {prefix}{i + 1}",
                                        r"image(\d{4})\.bmp", BODYTRACK_FRAME, first))
    initial = read_poses(root / "InitialPose.txt") if (root / "InitialPose.txt").exists() else None
    seq = Sequence(root=root, layout=BODYTRACK, rig=rig, model=model, image_paths=image_paths,
                   background_paths=[None] * len(rig), mask_paths=mask_paths, groundtruth=None,
                   initial_poses=initial, fps=None, meta={"source": "PARSEC bodytrack", "folder": str(root)},
                   diffusion_std=None if params is None else params.std)
    for v in range(len(rig)):
        seq.image(0, v)
        seq.mask(0, v)
    return seq


def _numbered(folder: Path, pattern: str, folders: bool) -> set[int]:
    """The numbers ``k`` of the entries of ``folder`` whose names match ``pattern`` (files, or folders)."""
    rx = re.compile(pattern)
    return {int(m.group(1)) for p in folder.iterdir() if (m := rx.fullmatch(p.name)) and p.is_dir() == folders}


def _bodytrack_cameras(root: Path) -> list[int]:
    """Camera numbers 1..N of a bodytrack folder; every ``CAMk/`` needs ``CALIB/Camerak.cal`` and vice versa."""
    cals = _numbered(root / "CALIB", r"Camera([1-9][0-9]*)\.cal", folders=False)
    if 1 not in cals:
        raise InputError("no CALIB/Camera1.cal: not a bodytrack folder", root)
    cams = _numbered(root, r"CAM([1-9][0-9]*)", folders=True)
    uncalibrated = sorted(cams - cals)
    if uncalibrated:
        k = uncalibrated[0]
        raise InputError(f"CAM{k}/ has images but CALIB/Camera{k}.cal is missing: every camera needs its "
                         "calibration (refusing to track with fewer views)", root)
    gaps = sorted(set(range(1, max(cals) + 1)) - cals)
    if gaps:
        raise InputError(f"CALIB/Camera{gaps[0]}.cal is missing: calibrations must be numbered 1..{max(cals)} "
                         "without gaps", root)
    return sorted(cals)


def read_sequence(root: str | Path, keypoints: bool = True) -> Sequence:
    """Open a sequence folder in either layout (own: ``cameras.json``; bodytrack: ``CALIB/``). ``keypoints``
    False leaves its ``keypoints/keypoints.npz`` unread (for what replaces that file, which may be broken)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError("not a sequence folder: a file" if root.exists() else "sequence folder does not exist", root)
    if (root / "cameras.json").exists():
        return _read_own(root, keypoints)
    if (root / "CALIB").is_dir():
        return _read_bodytrack(root)
    raise InputError("not a sequence folder: neither cameras.json nor a bodytrack CALIB/ folder", root)
