"""Multi-view sequences on disk: the project's own layout (reader and writer) and PARSEC bodytrack's (reader).

Own layout (DESIGN.md "Sequences on disk")::

    DIR/cameras.json                      the rig (tracker.core.cameras)
    DIR/images/<camera>/000000.png ...    one image per frame and camera
    DIR/background/<camera>.png           background plate, where there is one
    DIR/groundtruth.npz                   poses T x D, markers T x 15 x 3 (mm), fps -- when known
    DIR/meta.json                         source, subject, fps, body shape, generator settings

PARSEC bodytrack layout (read as it is)::

    DIR/CALIB/Camera1.cal ...  DIR/CAM1/image0000.bmp ...  DIR/FG1/image0000.bmp ...
    DIR/BodyShapeParameters.txt  DIR/InitialPose.txt  [DIR/PoseParameters.txt]

:func:`read_sequence` recognises either and returns a :class:`Sequence`. Images
come back as ``H x W x 3`` RGB uint8 (colour) or ``H x W`` uint8 (greyscale);
masks as ``H x W`` bool. Every problem (missing folder or frame, wrong image
size, unreadable file, empty mask) raises :class:`InputError` naming the file.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from tracker.core.body import BodyModel, BodyShape, fifteen_cone_model
from data_tools.calibration import read_bodytrack_calibration, read_cameras_json, write_cameras_json
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
        """Frame ``frame`` of camera ``view``: ``H x W x 3`` RGB or ``H x W`` grey, uint8."""
        self.check_frame(frame)
        return read_image(self.image_paths[view][frame], self.rig[view].width, self.rig[view].height)

    def background(self, view: int) -> np.ndarray | None:
        """The background plate of camera ``view`` (read once, then kept), or None."""
        path = self.background_paths[view]
        if path is None:
            return None
        if view not in self._plates:
            self._plates[view] = read_image(path, self.rig[view].width, self.rig[view].height)
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
        if self.mask_paths is not None:
            return Frame(frame, images, masks=tuple(self.mask(frame, v) for v in views))
        plates = [self.background(v) for v in views]
        missing = [self.rig[v].name for v, b in zip(views, plates) if b is None]
        if missing:
            raise InputError(f"no background plate and no masks for camera(s) {', '.join(missing)}", self.root)
        return Frame(frame, images, backgrounds=tuple(plates))


# ---------------------------------------------------------------------------
# Images
# ---------------------------------------------------------------------------

def read_image(path: Path, width: int, height: int) -> np.ndarray:
    """Read an image file and check its size against the camera's (``width`` x ``height`` pixels)."""
    path = Path(path)
    if not path.exists():
        raise InputError("image file is missing", path)
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError("cannot read image (unsupported or corrupt file)", path)
    if img.dtype != np.uint8:
        raise InputError(f"expected an 8-bit image, got {img.dtype}", path)
    if img.shape[:2] != (height, width):
        raise InputError(f"image is {img.shape[1]}x{img.shape[0]} pixels but its camera is {width}x{height}", path)
    if img.ndim == 3:
        if img.shape[2] == 4:
            img = img[..., :3]
        if img.shape[2] != 3:
            raise InputError(f"expected 1 or 3 channels, got {img.shape[2]}", path)
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return img


def read_mask(path: Path, width: int, height: int) -> np.ndarray:
    """A foreground mask (non-zero = person) as bool ``H x W``; an all-zero mask is refused."""
    img = read_image(path, width, height)
    mask = img > 0 if img.ndim == 2 else np.any(img > 0, axis=2)
    if not mask.any():
        raise InputError("foreground mask is all zero (no person)", path)
    return mask


def write_image(path: Path, image: np.ndarray) -> None:
    """Write ``H x W`` grey or ``H x W x 3`` RGB uint8 (PNG at compression level 1: fast)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if not cv2.imwrite(str(path), data, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
        raise InputError("cannot write image", path)


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
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read ground truth ({exc})", path) from None
    missing = [k for k in ("poses", "markers", "fps") if k not in data]
    if missing:
        raise InputError(f"ground truth lacks {', '.join(missing)}", path)
    poses, markers, fps = data["poses"], data["markers"], float(data["fps"])
    if poses.ndim != 2 or poses.shape[1] != n_dofs:
        raise InputError(f"poses must be T x {n_dofs}, got {poses.shape}", path)
    if markers.shape != (len(poses), 15, 3):
        raise InputError(f"markers must be {len(poses)} x 15 x 3, got {markers.shape}", path)
    if not (np.all(np.isfinite(poses)) and np.all(np.isfinite(markers)) and np.isfinite(fps) and fps > 0):
        raise InputError("ground truth contains NaN/infinite values or a non-positive fps", path)
    return GroundTruth(poses.astype(float), markers.astype(float), fps)


def write_meta(root: Path, meta: dict) -> None:
    (Path(root) / "meta.json").write_text(json.dumps(meta, indent=1, sort_keys=True))


def write_sequence_header(root: Path, rig: CameraRig, meta: dict) -> None:
    """Create ``root`` with ``cameras.json`` and ``meta.json`` (frames are written one by one)."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    write_cameras_json(rig, root / "cameras.json")
    write_meta(root, meta)


def _read_own(root: Path) -> Sequence:
    rig = read_cameras_json(root / "cameras.json")
    meta = {}
    if (root / "meta.json").exists():
        try:
            meta = json.loads((root / "meta.json").read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"not valid JSON: {exc.msg}", root / "meta.json", exc.lineno) from None
        if not isinstance(meta, dict):
            raise InputError("expected a JSON object", root / "meta.json")
    shape = meta.get("body_shape")
    model = fifteen_cone_model(BodyShape.from_dict(shape, str(root / "meta.json")) if shape else None)
    image_paths, backgrounds = [], []
    for cam in rig.cameras:
        first = (len(image_paths[0]), rig.names[0]) if image_paths else None
        image_paths.append(_camera_frames(root / "images" / cam.name, f"camera folder for {cam.name!r}",
                                          r"(\d{6})\.png", FRAME_NAME, first))
        bg = root / "background" / f"{cam.name}.png"
        backgrounds.append(bg if bg.exists() else None)
    gt = None
    if (root / "groundtruth.npz").exists():
        gt = read_groundtruth(root / "groundtruth.npz", model.n_dofs)
        if len(gt.poses) != len(image_paths[0]):
            raise InputError(f"ground truth has {len(gt.poses)} frames but the images have {len(image_paths[0])}",
                             root / "groundtruth.npz")
    fps = gt.fps if gt else meta.get("fps")
    seq = Sequence(root=root, layout=OWN, rig=rig, model=model, image_paths=image_paths,
                   background_paths=backgrounds, mask_paths=None, groundtruth=gt,
                   initial_poses=None if gt is None else gt.poses, fps=fps, meta=meta)
    for v in range(len(rig)):  # fail early on a wrong-sized or unreadable first frame
        seq.image(0, v)
    return seq


# ---------------------------------------------------------------------------
# PARSEC bodytrack layout
# ---------------------------------------------------------------------------

BODYTRACK_FRAME = "image{:04d}.bmp"


def _read_bodytrack(root: Path, width: int = 640, height: int = 480) -> Sequence:
    from data_tools.bodytrack import bodytrack_model, read_poses

    cal_files = []
    k = 1
    while (root / "CALIB" / f"Camera{k}.cal").exists():
        cal_files.append(root / "CALIB" / f"Camera{k}.cal")
        k += 1
    if not cal_files:
        raise InputError("no CALIB/Camera1.cal: not a bodytrack folder", root)
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


def read_sequence(root: str | Path) -> Sequence:
    """Open a sequence folder in either layout (own: ``cameras.json``; bodytrack: ``CALIB/``)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError("sequence folder does not exist", root)
    if (root / "cameras.json").exists():
        return _read_own(root)
    if (root / "CALIB").is_dir():
        return _read_bodytrack(root)
    raise InputError("not a sequence folder: neither cameras.json nor a bodytrack CALIB/ folder", root)
