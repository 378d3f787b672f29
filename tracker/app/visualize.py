"""Drawing the body model over images: projected cone outlines, filled model masks, view grids.

A truncated cone projects (without lens distortion exactly, with it nearly) to
the convex hull of its two projected end ellipses; each is sampled at 32
angles. Images are RGB ``H x W x 3`` uint8 (grey ones are converted), pixel
coordinates ``(x, y)``.
"""
from __future__ import annotations

import textwrap

import cv2
import numpy as np

from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.cones import cone_points, surface_grid
from tracker.core.kinematics import forward_kinematics

_ENDS = surface_grid(2, 32)

#: Outline colours (RGB) for left, right and central segments.
LEFT_COLOUR, RIGHT_COLOUR, CENTRE_COLOUR = (255, 60, 60), (60, 140, 255), (255, 230, 0)
#: The three colours as captions and documents name them (hue 0, 215 and 54 degrees).
COLOUR_NAMES = {"left": "red", "right": "light blue", "centre": "yellow"}


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
    """Draw one view's segment outlines on a copy of ``image`` (left red, right light blue, centre yellow)."""
    out = as_rgb(image)
    for seg, poly in zip(model.segments, polygons):
        if poly is not None:
            cv2.polylines(out, [_fixed_point(poly)], True, colour or _colour_of(seg.name), thickness,
                          lineType=cv2.LINE_AA, shift=4)
    return out


#: Colour (RGB) of the ground-truth outline.
TRUTH_COLOUR = (80, 255, 80)
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def label(image: np.ndarray, text: str, origin: tuple[int, int] = (6, 6), scale: float = 0.5) -> np.ndarray:
    """``text`` in white on a dark box whose top-left corner is ``origin`` (pixels). The box is sized from
    ``cv2.getTextSize``, so text and background agree with whatever OpenCV version draws them."""
    out = image.copy()
    (w, h), base = cv2.getTextSize(text, _FONT, scale, 1)
    x, y = origin
    cv2.rectangle(out, (x, y), (x + w + 8, y + h + base + 6), (0, 0, 0), thickness=-1)
    cv2.putText(out, text, (x + 4, y + h + 3), _FONT, scale, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def legend_strip(width: int, estimate: str | None, truth: bool, text: str = "") -> np.ndarray:
    """A dark ``32 x width`` strip naming the colours: the estimate's left, right and centre segments (and
    whose estimate it is), the ground truth, and ``text``."""
    strip = np.zeros((32, width, 3), np.uint8)
    x = 8
    items = []
    if estimate is not None:
        items += [(f"{estimate}:", None), ("left", LEFT_COLOUR), ("right", RIGHT_COLOUR), ("centre", CENTRE_COLOUR)]
    elif not truth:
        items += [("model:", None), ("left", LEFT_COLOUR), ("right", RIGHT_COLOUR), ("centre", CENTRE_COLOUR)]
    if truth:
        items.append(("ground truth", TRUTH_COLOUR))
    if text:
        items.append((text, None))
    for name, colour in items:
        if colour is not None:
            cv2.line(strip, (x, 16), (x + 18, 16), colour, 3, cv2.LINE_AA)
            x += 24
        cv2.putText(strip, name, (x, 21), _FONT, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        x += cv2.getTextSize(name, _FONT, 0.5, 1)[0][0] + 16
    return strip


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


def draw_estimate_and_truth(image: np.ndarray, model: BodyModel, estimate: list[np.ndarray | None] | None,
                            truth: list[np.ndarray | None] | None, thickness: int = 1) -> np.ndarray:
    """One view's estimate outlines (left/right/centre colours, ``thickness`` px) and, over them, the ground
    truth's as a thin outline (visible where the two coincide), on a copy of ``image``; either may be None."""
    out = as_rgb(image)
    if estimate is not None:
        out = draw_model(out, model, estimate, thickness)
    if truth is not None:
        out = draw_model(out, model, truth, 1, colour=TRUTH_COLOUR)
    return out


def scale_polygons(polygons: list[np.ndarray | None], scale: float, corner: tuple[int, int] = (0, 0)
                   ) -> list[np.ndarray | None]:
    """Outlines (pixels of an image) in the part of it from pixel ``corner`` (x, y) on, resized by ``scale``;
    pixel centres map to pixel centres (the origin is the centre of the top-left pixel)."""
    shift = np.asarray(corner, float)
    return [None if p is None else (p - shift + 0.5) * scale - 0.5 for p in polygons]


def text_strip(width: int, lines: list[str], scale: float = 0.45) -> np.ndarray:
    """A dark strip ``width`` pixels wide with ``lines`` of white text, one under the other; a line too long
    for the width is drawn smaller (down to 0.3), then cut with "..."."""
    height = int(round(22 * scale / 0.45))
    strip = np.zeros((height * len(lines) + 6, width, 3), np.uint8)
    for i, text in enumerate(lines):
        size = scale
        while size > 0.3 and cv2.getTextSize(text, _FONT, size, 1)[0][0] > width - 10:
            size -= 0.025
        while len(text) > 4 and cv2.getTextSize(text, _FONT, size, 1)[0][0] > width - 10:
            text = text[:-4] + "..."
        cv2.putText(strip, text, (5, height * (i + 1) - 3), _FONT, size, (255, 255, 255), 1, cv2.LINE_AA)
    return strip


def side_by_side(tiles: list[np.ndarray], gap: int = 4) -> np.ndarray:
    """RGB images of one height next to each other, ``gap`` dark pixels apart."""
    h = tiles[0].shape[0]
    if any(t.shape[0] != h for t in tiles):
        raise ValueError("side by side images must share one height")
    parts = []
    for i, tile in enumerate(tiles):
        if i:
            parts.append(np.zeros((h, gap, 3), np.uint8))
        parts.append(as_rgb(tile))
    return np.concatenate(parts, axis=1)


def overlay_grid(seq, pose: np.ndarray | None, frame: int, views: list[int], text: str = "",
                 thickness: int = 1, truth: np.ndarray | None = None, estimate_name: str | None = None
                 ) -> np.ndarray:
    """One RGB grid image of frame ``frame`` in the chosen views of ``seq`` (a
    :class:`data_tools.sequences.sequence.Sequence`): the model at ``pose`` in left/right/centre colours and, when
    given, the ground-truth pose ``truth`` as a thin outline over it (visible where the two coincide); each view is labelled with its
    camera, and a legend strip under the grid names the colours, ``estimate_name`` and ``text``."""
    rig = seq.rig.subset(views)
    est = None if pose is None else segment_polygons(seq.model, pose, rig)
    gt = None if truth is None else segment_polygons(seq.model, truth, rig)
    tiles = []
    for i, v in enumerate(views):
        img = draw_estimate_and_truth(seq.image(frame, v), seq.model, None if est is None else est[i],
                                      None if gt is None else gt[i], thickness)
        tiles.append(label(img, rig[i].name))
    canvas = grid(tiles)
    strip = legend_strip(canvas.shape[1], estimate_name if est is not None else None, gt is not None, text)
    return np.concatenate([canvas, strip])


def overlay_frames(seq, poses: np.ndarray, views: list[int], errors: np.ndarray | None = None, first: int = 0,
                   estimate_name: str = "estimate"):
    """Grid images frame by frame of ``poses`` ``T x D`` over the chosen views, with the ground truth where
    the sequence has it; ``errors`` (mm) of frames ``first ..`` are printed in the legend."""
    gt = seq.groundtruth
    for k in range(len(poses)):
        text = f"frame {k}"
        if errors is not None and k >= first:
            text += f", error {errors[k - first]:.0f} mm"
        truth = gt.poses[k] if gt is not None and k < len(gt.poses) else None
        yield overlay_grid(seq, poses[k], k, views, text, thickness=2, truth=truth, estimate_name=estimate_name)


def write_video(path, frames, fps: float, crf: int = 20) -> None:
    """Write RGB frames (an iterable of equal-sized ``H x W x 3`` uint8) to an H.264 .mp4 (yuv420p, which
    browsers and slide software play) with PyAV; odd sizes are padded by a pixel; ``crf`` is x264's constant
    rate factor (higher: smaller and coarser). Written atomically: a failure part-way leaves no truncated video
    behind."""
    from pathlib import Path

    import av

    from data_tools.io.files import atomic_path
    from tracker.core.errors import InputError

    path = Path(path)
    with atomic_path(path) as tmp:
        container = av.open(str(tmp), mode="w")
        try:
            stream = None
            for img in frames:
                h, w = img.shape[:2]
                if stream is None:
                    stream = container.add_stream("libx264", rate=round(float(fps)))
                    stream.width, stream.height = w + w % 2, h + h % 2
                    stream.pix_fmt = "yuv420p"
                    stream.options = {"crf": str(crf), "preset": "veryfast"}
                if (h + h % 2, w + w % 2) != (stream.height, stream.width):
                    raise InputError(f"video frames must share one size: {w}x{h} after "
                                     f"{stream.width}x{stream.height}", path)
                if w % 2 or h % 2:
                    img = np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)))
                frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(img), format="rgb24")
                for packet in stream.encode(frame):
                    container.mux(packet)
            if stream is None:
                raise InputError("no frames to write", path)
            for packet in stream.encode():
                container.mux(packet)
        finally:
            container.close()


def error_plot(path, curves: dict[str, tuple[np.ndarray, np.ndarray]], title: str) -> None:
    """Marker error per frame (mm), one line per run: ``{label: (frames, errors)}``; PNG via matplotlib. More than
    three runs get their legend beside the axes, where it hides no line.

    Draws on a bare :class:`matplotlib.figure.Figure`, never through pyplot, so the process's matplotlib
    backend (a notebook's inline plots) is left alone."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from data_tools.io.files import atomic_path

    beside = len(curves) > 3
    fig = Figure(figsize=(9.5 if beside else 7, 3.5), dpi=120)
    ax = fig.subplots()
    for name, (frames, errs) in curves.items():
        ax.plot(frames, errs, label=f"{name} (mean {np.mean(errs):.0f} mm)")
    ax.set_xlabel("frame")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("marker error (mm)")
    ax.set_title("\n".join(textwrap.wrap(title, 72)))  # a long title on two lines, not cut at the edges
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(**({"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "fontsize": "small"} if beside else {}))
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp)


def summary_plot(path, summary: dict, title: str, truth: list[tuple[int, int, str]] | None = None) -> None:
    """The prior's per-frame summary (``TrackingResult.prior_summary``: e.g. the posterior over style labels) as
    stacked areas over the tracked frames, with optional true segments ``(first, last, name)`` drawn as a bar
    above; a summary of kind ``"quantity"`` (e.g. the paced CRBM's posterior mean pace, a height offset) is drawn as
    one line per quantity, each in its own panel with its own scale (a signed quantity may go below 0). PNG via
    matplotlib (a bare Figure, as :func:`error_plot`)."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    from data_tools.io.files import atomic_path

    rows = np.asarray(summary["per_frame"], float)
    frames = summary["first_frame"] + np.arange(len(rows))
    colours = [f"C{i}" for i in range(len(summary["names"]))]
    if summary.get("kind", "posterior") == "quantity":
        n = len(summary["names"])
        fig = Figure(figsize=(7, 1.2 + 1.8 * n), dpi=120)
        axes = np.atleast_1d(fig.subplots(n, 1, sharex=True))
        for k, (ax, name) in enumerate(zip(axes, summary["names"])):
            values = rows[:, k] if rows.size else np.zeros(0)
            ax.plot(frames, values, color=colours[k], label=name)
            ax.set_ylabel(name, fontsize=8)
            finite = values[np.isfinite(values)]
            if finite.size == 0 or finite.min() >= 0:  # a speed: from standing still
                ax.set_ylim(0, max(1.0, 1.1 * float(finite.max())) if finite.size else 1.0)
        axes[0].set_title(title)
        ax = axes[-1]
    else:
        fig = Figure(figsize=(7, 3), dpi=120)
        ax = fig.subplots()
        ax.stackplot(frames, rows.T, labels=summary["names"], colors=colours, alpha=0.8, step="mid")
        for first, last, name in truth or []:
            k = summary["names"].index(name) if name in summary["names"] else 0
            ax.plot([first, last], [1.04, 1.04], color=colours[k], lw=6, solid_capstyle="butt")
        ax.set_ylabel("posterior")
        ax.set_ylim(0, 1.08)
        ax.set_title(title)
        ax.legend(loc="lower left", fontsize=8)
    ax.set_xlabel("frame")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
