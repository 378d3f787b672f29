"""Video files in: one video per calibrated camera becomes a sequence folder (:mod:`data_tools.sequences.sequence`).

:func:`import_videos` pairs videos with cameras (by sorted name, or an explicit mapping), checks that the videos
agree on frame rate and frame count (one line naming them when they do not, and ``frames`` to choose a common
range), checks each video's size against its camera's (portrait or landscape alike; a video a few pixels
narrower or shorter than its calibration, as encoders crop to a multiple of 8 or 16, keeps the intrinsics: its
pixels are counted from the top-left corner as the calibration's are, and its missing right columns and bottom
rows are filled with its last ones, so that every camera's frames have the calibrated size and a rig of one
image size stays one), optionally shrinks the frames with the
intrinsics scaled to match, and writes ``cameras.json``, ``images/<camera>/NNNNNN.png`` and ``meta.json``.
Frames are decoded one at a time as they are written, never all held in memory. OpenCV's ``VideoCapture``
decodes (it applies a file's rotation metadata, so phone videos come upright).
"""
from __future__ import annotations

import os
import re
import shutil
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping, Sequence

import cv2
import numpy as np

from data_tools.io.files import fresh_beside
from data_tools.sequences.calibration import checked_camera
from data_tools.sequences.rig_formats import read_rig
from data_tools.sequences.sequence import FRAME_NAME, _stderr_silenced, write_image, write_sequence_header
from data_tools.vision.import_settings import import_option
from tracker.core.cameras import Camera, CameraRig
from tracker.core.errors import InputError

#: A video at most this fraction smaller than its calibration in width and in height (and never larger) is taken
#: to be the calibrated image cropped at its right and bottom edges.
SIZE_TOLERANCE = 0.01
#: Frame rates closer than this (Hz) are the same rate.
FPS_TOLERANCE = 0.01


@dataclass(frozen=True)
class VideoInfo:
    """What a video file says of itself: pixel size, frame rate (Hz) and frame count."""

    path: Path
    width: int
    height: int
    fps: float
    frames: int


def probe_video(path: str | Path) -> VideoInfo:
    """Open a video and read its size, rate and frame count (the container's count, checked while decoding)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("video file does not exist", path)
    cap = _open(path)
    try:
        width, height = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fps, frames = float(cap.get(cv2.CAP_PROP_FPS)), int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    if width <= 0 or height <= 0:
        raise InputError("cannot read the video's frame size", path)
    if not np.isfinite(fps) or fps <= 0:
        raise InputError("the video gives no frame rate", path)
    if frames <= 0:
        raise InputError("the video gives no frame count (or has no frames)", path)
    return VideoInfo(path, width, height, fps, frames)


def _open(path: Path) -> cv2.VideoCapture:
    with _stderr_silenced():
        cap = cv2.VideoCapture(str(path))
        ok = cap.isOpened()
    if not ok:
        raise InputError("cannot open as a video (not a video file, or a codec this OpenCV lacks)", path)
    return cap


def video_frames(info: VideoInfo, start: int = 0, stop: int | None = None) -> Iterator[np.ndarray]:
    """Frames ``start..stop-1`` of a video as ``H x W x 3`` RGB uint8, decoded one at a time."""
    stop = info.frames if stop is None else stop
    cap = _open(info.path)
    try:
        for k in range(stop):
            with _stderr_silenced():
                ok, frame = cap.read()
            if not ok:
                raise InputError(f"the video ends after {k} frames though it says it has {info.frames}; give a "
                                 f"frame range within 0:{k}", info.path)
            if k >= start:
                yield cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
    finally:
        cap.release()


def pair_videos(cameras: Sequence[str], videos: Sequence[Path],
                mapping: Mapping[str, str] | None = None) -> list[Path]:
    """The video of each camera, in the cameras' order.

    Without ``mapping``, the videos sorted by file name go to the cameras sorted by name (``cam01.mp4`` ...
    ``cam04.mp4`` to ``cam_01`` ... ``cam_04``). ``mapping`` (camera name -> video file name or path) pairs them
    explicitly; cameras it leaves out are not imported.
    """
    videos = [Path(v) for v in videos]
    if mapping:
        unknown = sorted(set(mapping) - set(cameras))
        if unknown:
            raise InputError(f"the camera mapping names {unknown[0]!r}, which the calibration lacks (its cameras: "
                             f"{', '.join(cameras)})")
        by_name = {v.name: v for v in videos} | {str(v): v for v in videos}
        out = []
        for cam in [c for c in cameras if c in mapping]:
            video = by_name.get(mapping[cam]) or by_name.get(Path(mapping[cam]).name)
            if video is None:
                raise InputError(f"the camera mapping gives {mapping[cam]!r} for {cam!r}, which is not one of the "
                                 f"videos ({', '.join(v.name for v in videos)})")
            out.append(video)
        if len(set(out)) != len(out):
            raise InputError("the camera mapping gives one video to several cameras")
        return out
    if len(videos) != len(cameras):
        raise InputError(f"{len(videos)} video(s) for {len(cameras)} calibrated cameras ({', '.join(cameras)}): "
                         "give one video per camera, or a mapping camera=video")
    order = sorted(range(len(cameras)), key=lambda i: _natural(cameras[i]))
    ranked = sorted(videos, key=lambda v: _natural(v.name))
    out: list[Path] = [Path()] * len(cameras)
    for i, video in zip(order, ranked):
        out[i] = video
    return out


def _natural(text: str) -> list:
    """Sort key that orders ``cam2`` before ``cam10``."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", text)]


def common_range(infos: Sequence[VideoInfo], frames: tuple[int, int | None] | None) -> tuple[int, int]:
    """The frames ``[start, stop)`` to import: all of them when the counts agree, else ``frames`` (checked)."""
    counts = [i.frames for i in infos]
    shortest = min(counts)
    if frames is None:
        if len(set(counts)) > 1:
            listed = ", ".join(f"{i.path.name} {i.frames}" for i in infos)
            raise InputError(f"the videos' frame counts differ ({listed}): give a common frame range, e.g. "
                             f"--frames 0:{shortest}")
        return 0, shortest
    start, stop = frames
    stop = shortest if stop is None else stop
    if not 0 <= start < stop <= shortest:
        raise InputError(f"frame range {start}:{stop} is not within 0:{shortest} (the shortest video has "
                         f"{shortest} frames)")
    return start, stop


def parse_frame_range(text: str) -> tuple[int, int | None]:
    """``"A:B"`` (B exclusive), ``"A:"`` (to the end) -> (A, B or None)."""
    m = re.fullmatch(r"\s*(\d+)\s*:\s*(\d*)\s*", text)
    if not m:
        raise InputError(f"a frame range is A:B (first frame, one past the last) or A:, got {text!r}")
    return int(m.group(1)), int(m.group(2)) if m.group(2) else None


def padded(frame: np.ndarray, width: int, height: int) -> np.ndarray:
    """``frame`` (``h x w x 3``, at most ``width`` x ``height``) grown to ``height x width`` by repeating its last
    column and row: the calibrated image of a video cropped at its right and bottom edges."""
    h, w = frame.shape[:2]
    if (w, h) == (width, height):
        return frame
    return cv2.copyMakeBorder(frame, 0, height - h, 0, width - w, cv2.BORDER_REPLICATE)


def fitted_camera(cam: Camera, info: VideoInfo, downscale: float = 1.0) -> Camera:
    """``cam`` for the frames of ``info`` shrunk by ``downscale``: sizes checked, intrinsics scaled.

    Pixel centres are the coordinates (``tracker.core.cameras``), so shrinking by ``s`` maps ``u`` to
    ``(u + 0.5) / s - 0.5``.
    """
    W, H = info.width, info.height
    if (W, H) != (cam.width, cam.height):
        if (W, H) == (cam.height, cam.width):
            raise InputError(f"the video is {W}x{H} but camera {cam.name!r} is calibrated at {cam.width}x"
                             f"{cam.height}: turned by 90 degrees (rotate the video, or calibrate it as it is)",
                             info.path)
        if not (cam.width * (1 - SIZE_TOLERANCE) <= W <= cam.width
                and cam.height * (1 - SIZE_TOLERANCE) <= H <= cam.height):
            raise InputError(f"the video is {W}x{H} but camera {cam.name!r} is calibrated at {cam.width}x"
                             f"{cam.height}", info.path)
    W, H = cam.width, cam.height  # a cropped video is padded back to the calibrated size (import_videos)
    w, h = int(round(W / downscale)), int(round(H / downscale))
    sx, sy = w / W, h / H
    return checked_camera(cam.name, w, h, cam.fx * sx, cam.fy * sy, (cam.cx + 0.5) * sx - 0.5,
                          (cam.cy + 0.5) * sy - 0.5, cam.R, cam.t, skew=cam.skew, dist=cam.dist, source=info.path)


@dataclass
class ImportResult:
    """What :func:`import_videos` wrote: the folder, the rig, the frame range of the videos, the rate (Hz)."""

    root: Path
    rig: CameraRig
    videos: list[Path]
    start: int
    stop: int
    fps: float
    notes: list[str]

    @property
    def n_frames(self) -> int:
        return self.stop - self.start


@contextmanager
def staged_folder(out: Path) -> Iterator[Path]:
    """A temporary folder beside ``out`` to write an imported sequence into; when the block succeeds its entries
    replace ``out``'s (an earlier import's ``images/``, ``masks/`` and ``keypoints/`` go, so frames are never
    mixed with another import's; other files stay), and when it fails or is interrupted it is removed and ``out``
    is left as it was."""
    with fresh_beside(out, ".tmp", directory=True) as staged:
        yield staged
        out.mkdir(exist_ok=True)
        for stale in ("images", "masks", "keypoints"):  # per frame and camera: of the earlier import
            if (out / stale).is_dir():
                shutil.rmtree(out / stale)
        for entry in staged.iterdir():  # made by plain open and mkdir: their modes follow the umask already
            os.replace(entry, out / entry.name)
        staged.rmdir()


def import_videos(calibration: str | Path | Sequence[str | Path], videos: Sequence[str | Path], out: str | Path, *,
                  downscale: float = import_option("downscale").default,
                  frames: tuple[int, int | None] | str | None = None,
                  mapping: Mapping[str, str] | None = None,
                  progress: Callable[[Iterable], Iterable] | None = None) -> ImportResult:
    """Turn one video per calibrated camera into a sequence folder ``out`` that ``track`` reads.

    ``calibration``: a file :func:`data_tools.sequences.rig_formats.read_rig` reads (or two OpenCV files); ``downscale``
    shrinks every frame by that factor (>= 1) with the intrinsics scaled; ``frames`` is ``(start, stop)`` or
    ``"A:B"``, required when the videos' counts differ; ``mapping`` pairs cameras with videos by name
    (:func:`pair_videos`). The folder has no background plates: add silhouettes (``masks/``) before tracking.
    """
    downscale = import_option("downscale").parse(downscale, "import")
    if isinstance(frames, str):
        frames = parse_frame_range(frames)
    videos = [Path(v) for v in videos]
    if not videos:
        raise InputError("no video given")
    probed = {v: probe_video(v) for v in videos}
    rig = _read_rig_for(calibration, videos, probed, mapping)
    paired = pair_videos(rig.names, videos, mapping)
    cams = [c for c in rig.cameras if not mapping or c.name in mapping]
    infos = [probed[v] for v in paired]
    if max(i.fps for i in infos) - min(i.fps for i in infos) > FPS_TOLERANCE:
        listed = ", ".join(f"{i.path.name} {i.fps:g} Hz" for i in infos)
        raise InputError(f"the videos' frame rates differ ({listed}): resample them to one rate first")
    start, stop = common_range(infos, frames)
    fitted = CameraRig([fitted_camera(c, i, downscale) for c, i in zip(cams, infos)])
    notes = [f"{c.name} <- {i.path.name} ({i.width}x{i.height}, {i.frames} frames at {i.fps:g} Hz)"
             + (f", calibrated at {c.width}x{c.height}: cropped at the right and bottom edges, padded back with "
                "its last pixels"
                if (i.width, i.height) != (c.width, c.height) else "")
             for c, i in zip(cams, infos)]
    out = Path(out)
    meta = {"source": "videos", "videos": [str(v) for v in paired], "calibration": str(calibration),
            "fps": float(infos[0].fps), "first_video_frame": start, "downscale": float(downscale)}
    with staged_folder(out) as staged:
        write_sequence_header(staged, fitted, meta)
        steps = range(len(cams))
        for v in (progress(steps) if progress else steps):
            cam = fitted[v]
            for k, frame in enumerate(video_frames(infos[v], start, stop)):
                if frame.shape[:2] != (infos[v].height, infos[v].width):
                    raise InputError(f"frame {start + k} is {frame.shape[1]}x{frame.shape[0]}, not the video's "
                                     f"{infos[v].width}x{infos[v].height}", infos[v].path)
                frame = padded(frame, cams[v].width, cams[v].height)
                if (cam.width, cam.height) != (cams[v].width, cams[v].height):
                    frame = cv2.resize(frame, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
                write_image(staged / "images" / cam.name / FRAME_NAME.format(k), frame)
    return ImportResult(out, fitted, paired, start, stop, float(infos[0].fps), notes)


def _read_rig_for(calibration, videos: Sequence[Path], probed: Mapping[Path, VideoInfo],
                  mapping: Mapping[str, str] | None) -> CameraRig:
    """The calibration's rig; where the file gives no image sizes, the paired videos' sizes."""
    try:
        return read_rig(calibration)
    except InputError as exc:
        if "no image size" not in exc.reason:
            raise
    from data_tools.sequences.rig_formats import camera_names

    names = camera_names(calibration)
    paired = pair_videos(names, videos, mapping)
    chosen = [n for n in names if not mapping or n in mapping]
    return read_rig(calibration, sizes={n: (probed[v].width, probed[v].height) for n, v in zip(chosen, paired)})
