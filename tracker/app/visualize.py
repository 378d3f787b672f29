"""Drawing the body model over images: projected cone outlines, filled model masks, view grids.

A truncated cone projects (without lens distortion exactly, with it nearly) to
the convex hull of its two projected end ellipses; each is sampled at 32
angles. Images are RGB ``H x W x 3`` uint8 (grey ones are converted), pixel
coordinates ``(x, y)``.
"""
from __future__ import annotations

import cv2
import numpy as np

from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.cones import cone_points, surface_grid
from tracker.core.kinematics import forward_kinematics

_ENDS = surface_grid(2, 32)

#: Outline colours (RGB) for left, right and central segments.
LEFT_COLOUR, RIGHT_COLOUR, CENTRE_COLOUR = (255, 60, 60), (60, 140, 255), (255, 230, 0)


def segment_polygons(model: BodyModel, pose: np.ndarray, rig: CameraRig) -> list[list[np.ndarray | None]]:
    """Projected outline of every segment in every view: ``[view][segment]`` -> ``n x 2`` pixels (float), or
    ``None`` where the segment is (partly) behind that camera."""
    frames = forward_kinematics(model, np.asarray(pose, float)).segment_frames()  # S x 4 x 4
    pts = cone_points(model, frames, *_ENDS)  # S x K x 3
    pix, depth = rig.project(pts)  # S x V x K x 2 ... projected per segment
    out = []
    for v in range(len(rig)):
        polys = []
        for s in range(len(model.segments)):
            if np.any(depth[s, v] <= 0):
                polys.append(None)
                continue
            hull = cv2.convexHull(pix[s, v].astype(np.float32))
            polys.append(hull.reshape(-1, 2).astype(float))
        out.append(polys)
    return out


def model_masks(model: BodyModel, pose: np.ndarray, rig: CameraRig) -> list[np.ndarray]:
    """Bool ``H x W`` mask per view of the pixels covered by the projected model at ``pose``."""
    masks = []
    for v, polys in enumerate(segment_polygons(model, pose, rig)):
        cam = rig[v]
        m = np.zeros((cam.height, cam.width), np.uint8)
        for poly in polys:
            if poly is not None:
                cv2.fillConvexPoly(m, _fixed_point(poly), 1, lineType=cv2.LINE_8, shift=4)
        masks.append(m.astype(bool))
    return masks


def _fixed_point(poly: np.ndarray) -> np.ndarray:
    """Pixel coordinates to OpenCV's 4-bit fixed point (sub-pixel drawing)."""
    return np.rint(poly * 16.0).astype(np.int32).reshape(-1, 1, 2)


def _colour_of(name: str) -> tuple[int, int, int]:
    if name.startswith("left_"):
        return LEFT_COLOUR
    if name.startswith("right_"):
        return RIGHT_COLOUR
    return CENTRE_COLOUR


def as_rgb(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB) if image.ndim == 2 else image.copy()


def draw_model(image: np.ndarray, model: BodyModel, polygons: list[np.ndarray | None],
               thickness: int = 1, colour: tuple[int, int, int] | None = None) -> np.ndarray:
    """Draw one view's segment outlines on a copy of ``image`` (left red, right blue, centre yellow)."""
    out = as_rgb(image)
    for seg, poly in zip(model.segments, polygons):
        if poly is not None:
            cv2.polylines(out, [_fixed_point(poly)], True, colour or _colour_of(seg.name), thickness,
                          lineType=cv2.LINE_AA, shift=4)
    return out


def label(image: np.ndarray, text: str) -> np.ndarray:
    out = image.copy()
    cv2.putText(out, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def grid(images: list[np.ndarray], columns: int | None = None) -> np.ndarray:
    """Tile RGB images of equal size into a grid (``columns`` default: 2 for up to 4 views, else 3)."""
    if not images:
        raise ValueError("no images to tile")
    h, w = images[0].shape[:2]
    columns = columns or (min(2, len(images)) if len(images) <= 4 else 3)
    rows = -(-len(images) // columns)
    canvas = np.zeros((rows * h, columns * w, 3), np.uint8)
    for i, img in enumerate(images):
        r, c = divmod(i, columns)
        canvas[r * h:(r + 1) * h, c * w:(c + 1) * w] = cv2.resize(as_rgb(img), (w, h))
    return canvas


def overlay_grid(seq, pose: np.ndarray, frame: int, views: list[int], text: str = "",
                 thickness: int = 1) -> np.ndarray:
    """One RGB grid image: the model at ``pose`` drawn over frame ``frame`` of the chosen views of ``seq``
    (a :class:`data_tools.sequence.Sequence`), each view labelled with its camera name and ``text``."""
    rig = seq.rig.subset(views)
    polys = segment_polygons(seq.model, pose, rig)
    return grid([label(draw_model(seq.image(frame, v), seq.model, polys[i], thickness), f"{rig[i].name}  {text}")
                 for i, v in enumerate(views)])


def overlay_frames(seq, poses: np.ndarray, views: list[int], errors: np.ndarray | None = None, first: int = 0):
    """Grid images frame by frame of ``poses`` ``T x D`` over the chosen views; ``errors`` (mm) of frames
    ``first ..`` are printed on them."""
    for k in range(len(poses)):
        text = f"frame {k}"
        if errors is not None and k >= first:
            text += f"  error {errors[k - first]:.0f} mm"
        yield overlay_grid(seq, poses[k], k, views, text, thickness=2)


def write_video(path, frames, fps: float) -> None:
    """Write RGB frames (an iterable of equal-sized ``H x W x 3`` uint8) to an .mp4 (MPEG-4 part 2)."""
    from pathlib import Path

    from tracker.core.errors import InputError

    from data_tools.files import atomic_path

    path = Path(path)
    writer = None
    with atomic_path(path) as tmp:  # a failure part-way leaves no truncated video behind
        try:
            for img in frames:
                if writer is None:
                    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), float(fps),
                                             (img.shape[1], img.shape[0]))
                    if not writer.isOpened():
                        raise InputError("cannot open the video for writing", path)
                writer.write(cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        finally:
            if writer is not None:
                writer.release()


def error_plot(path, curves: dict[str, tuple[np.ndarray, np.ndarray]], title: str) -> None:
    """Marker error per frame (mm), one line per run: ``{label: (frames, errors)}``; PNG via matplotlib.

    Draws on a bare :class:`matplotlib.figure.Figure`, never through pyplot, so the process's matplotlib
    backend (a notebook's inline plots) is left alone."""
    from matplotlib.figure import Figure

    from data_tools.files import atomic_path

    fig = Figure(figsize=(7, 3.5), dpi=120)
    ax = fig.subplots()
    for name, (frames, errs) in curves.items():
        ax.plot(frames, errs, label=f"{name} (mean {np.mean(errs):.0f} mm)")
    ax.set_xlabel("frame")
    ax.set_ylabel("marker error (mm)")
    ax.set_title(title)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
