"""Command line: ``python -m tracker <command>`` (the contract: DESIGN.md "Command line", README).

Every bad input ends with a one-line reason on stderr and exit status 2.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from tracker.errors import InputError


def _number(kind: type, minimum: float, strict: bool):
    """An argparse type: ``kind`` (int or float), finite, above (``strict``) or at least ``minimum``."""
    noun = "an integer" if kind is int else "a number"
    bound = f"greater than {minimum:g}" if strict else f"at least {minimum:g}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None
        if not np.isfinite(value) or value < minimum or (strict and value == minimum):
            raise argparse.ArgumentTypeError(f"must be {bound}, got {text}")
        return value

    return parse


_positive_float = _number(float, 0.0, strict=True)
_non_negative_float = _number(float, 0.0, strict=False)
_positive_int = _number(int, 1, strict=False)
_non_negative_int = _number(int, 0, strict=False)


class _Parser(argparse.ArgumentParser):
    """argparse with exit status 2 and a one-line message for usage errors."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m tracker",
                description="3D human pose tracking with learned dynamical priors.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    c = sub.add_parser("convert", help="convert a mocap clip (AMC+ASF or BVH) to body-model poses and markers",
                       description="Retarget a mocap clip to the 15-cone body model and write CLIP.npz with "
                                   "poses, markers (ground truth), model_markers, fps and the body shape.")
    c.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    c.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    c.add_argument("--fps", type=_positive_float, default=60.0, help="output frame rate in Hz (default 60)")
    c.add_argument("--length-unit", type=_positive_float, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred from the skeleton's height)")
    c.add_argument("--out", required=True, help="output .npz")

    s = sub.add_parser("synth", help="render a mocap clip into a synthetic multi-view sequence",
                       description="Retarget a mocap clip, render it into a calibrated rig over a cluttered room "
                                   "and write the sequence folder (cameras.json, images/, background/, "
                                   "groundtruth.npz, meta.json).")
    s.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    s.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    s.add_argument("--out", required=True, help="output sequence folder")
    s.add_argument("--views", type=_positive_int, default=4, help="number of cameras (default 4)")
    s.add_argument("--fps", type=_positive_float, default=60.0, help="frame rate in Hz (default 60)")
    s.add_argument("--start", type=_non_negative_int, default=0, help="first frame, at the output rate (default 0)")
    s.add_argument("--frames", type=_positive_int, default=None, help="number of frames (default: to the end)")
    s.add_argument("--seed", type=int, default=0, help="random seed: scene, clothing, widths, noise (default 0)")
    s.add_argument("--width", type=_positive_int, default=640, help="image width in pixels (default 640)")
    s.add_argument("--height", type=_positive_int, default=480, help="image height in pixels (default 480)")
    s.add_argument("--noise", type=_non_negative_float, default=2.0,
                   help="sensor noise std in grey levels of 255 (default 2)")
    s.add_argument("--lighting-change", type=float, default=0.0, metavar="FRACTION",
                   help="brightness drifts from 1 to 1+FRACTION over the sequence (default 0)")
    s.add_argument("--occluder", action="store_true", help="put a pillar between camera 0 and the person")
    s.add_argument("--missing-camera", type=_non_negative_int, default=None, metavar="INDEX",
                   help="this camera delivers only black frames")
    s.add_argument("--length-unit", type=_positive_float, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred)")

    w = sub.add_parser("show", help="draw the projected body model over every view of a sequence frame",
                       description="Draw the projected cones (ground truth, the initial pose, or --poses) over "
                                   "every camera view in one grid image, or a whole sequence as a video.")
    w.add_argument("sequence", metavar="DIR", help="sequence folder (own layout or PARSEC bodytrack)")
    w.add_argument("--frame", type=_non_negative_int, default=0, help="frame to draw (default 0)")
    w.add_argument("--poses", help="estimates.npz (poses T x D) to draw instead of the ground truth")
    w.add_argument("--out", help="output image (.png)")
    w.add_argument("--video", help="also write every frame to this video (.mp4)")

    d = sub.add_parser("demo", help="run the built-in demo on the shipped sample walks",
                       description="Convert the shipped CMU subject-7 walks and print a summary of each.")
    d.add_argument("--out", default="demo_output", help="output folder (default ./demo_output)")
    return p


def _convert_one(mocap: str | Path, skeleton, fps: float, length_unit, out: Path):
    from data_tools.clip_io import save_converted_clip
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget

    clip = load_mocap(mocap, skeleton, length_unit)
    result = retarget(clip, fps=fps)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_converted_clip(result, out)
    return clip, result


def cmd_convert(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix != ".npz":
        raise InputError("output must be a .npz file", out)
    clip, result = _convert_one(args.mocap, args.skeleton, args.fps, args.length_unit, out)
    for note in clip.notes:
        print(f"note: {Path(args.mocap).name}: {note}", file=sys.stderr)
    print(f"{Path(args.mocap).name}: {len(result.poses)} frames at {result.fps:g} fps, "
          f"mean retarget residual {result.mean_residual:.2f} mm -> {out}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from data_tools.samples import CMU_ATTRIBUTION, sample_walks
    from tracker.body import standing_height

    out = Path(args.out)
    asf, walks = sample_walks()
    print(f"Converting {len(walks)} shipped walks of CMU subject 7 to the 15-cone body model (60 Hz):")
    for amc in walks:
        target = out / (amc.stem + ".npz")
        _, r = _convert_one(amc, asf, 60.0, None, target)
        root = r.poses[:, :2]
        path_m = float(np.linalg.norm(np.diff(root, axis=0), axis=1).sum()) / 1000.0
        secs = (len(r.poses) - 1) / r.fps
        print(f"  {amc.stem}: {len(r.poses)} frames ({secs:.2f} s), walked {path_m:.2f} m at "
              f"{path_m / secs:.2f} m/s, subject {standing_height(r.model) / 1000:.2f} m tall, "
              f"retarget residual {r.mean_residual:.2f} mm -> {target}")
    print(CMU_ATTRIBUTION)
    return 0


def cmd_synth(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from data_tools.synth import SynthSettings, synthesize

    settings = SynthSettings(views=args.views, fps=args.fps, start=args.start, frames=args.frames, seed=args.seed,
                             width=args.width, height=args.height, noise=args.noise,
                             lighting_change=args.lighting_change, occluder=args.occluder,
                             missing_camera=args.missing_camera)
    clip = load_mocap(args.mocap, args.skeleton, args.length_unit)
    for note in clip.notes:
        print(f"note: {Path(args.mocap).name}: {note}", file=sys.stderr)
    result = retarget(clip, fps=args.fps)
    out = synthesize(result, args.out, settings, source=str(args.mocap),
                     progress=lambda it: tqdm(it, desc="rendering", unit="frame"))
    print(f"{Path(args.mocap).name}: {out.n_frames} frames x {args.views} views at "
          f"{result.fps:g} fps -> {out.root} ({out.render_seconds / out.n_frames * 1000:.0f} ms per frame "
          f"to render and write)")
    return 0


def _poses_to_draw(seq, poses_file: str | None) -> np.ndarray:
    """Poses T x D to draw: from ``--poses``, else the ground truth, else the initial pose(s)."""
    if poses_file:
        path = Path(poses_file)
        try:
            with np.load(path, allow_pickle=False) as z:
                if "poses" not in z.files:
                    raise InputError("no 'poses' array in the file", path)
                poses = np.asarray(z["poses"], float)
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read poses ({exc})", path) from None
        if poses.ndim != 2 or poses.shape[1] != seq.model.n_dofs:
            raise InputError(f"poses must be T x {seq.model.n_dofs} for the {seq.model.name} model, got "
                             f"{poses.shape}", path)
        if not np.all(np.isfinite(poses)):
            raise InputError("poses contain NaN or infinite values", path)
        return poses
    if seq.groundtruth is not None:
        return seq.groundtruth.poses
    if seq.initial_poses is not None:
        return seq.initial_poses
    raise InputError("the sequence has no ground truth or initial pose; give --poses", seq.root)


def _overlay_grid(seq, poses: np.ndarray, frame: int) -> np.ndarray:
    from tracker.visualize import draw_model, grid, label, segment_polygons

    polys = segment_polygons(seq.model, poses[frame], seq.rig)
    views = [label(draw_model(seq.image(frame, v), seq.model, polys[v]), f"{seq.rig[v].name}  frame {frame}")
             for v in range(seq.n_views)]
    return grid(views)


def write_video(path: Path, frames, fps: float) -> None:
    """Write RGB frames (an iterable of equal-sized H x W x 3 uint8) to an .mp4 (MPEG-4 part 2)."""
    import cv2

    writer = None
    try:
        for img in frames:
            if writer is None:
                path.parent.mkdir(parents=True, exist_ok=True)
                writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(fps),
                                         (img.shape[1], img.shape[0]))
                if not writer.isOpened():
                    raise InputError("cannot open the video for writing", path)
            writer.write(cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    finally:
        if writer is not None:
            writer.release()


def cmd_show(args: argparse.Namespace) -> int:
    import cv2
    from tqdm import tqdm

    from data_tools.sequence import read_sequence

    if not args.out and not args.video:
        raise InputError("nothing to write: give --out FILE.png and/or --video FILE.mp4")
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise InputError("--out must be a .png file", args.out)
    if args.video and Path(args.video).suffix.lower() != ".mp4":
        raise InputError("--video must be an .mp4 file", args.video)
    seq = read_sequence(args.sequence)
    poses = _poses_to_draw(seq, args.poses)
    seq.check_frame(args.frame)
    if args.frame >= len(poses):
        raise InputError(f"no pose for frame {args.frame}: {len(poses)} pose(s) available", args.poses or seq.root)
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(out), cv2.cvtColor(_overlay_grid(seq, poses, args.frame), cv2.COLOR_RGB2BGR)):
            raise InputError("cannot write image", out)
        print(f"frame {args.frame}, {seq.n_views} views -> {out}")
    if args.video:
        n = min(seq.n_frames, len(poses))
        frames = (_overlay_grid(seq, poses, k) for k in tqdm(range(n), desc="video", unit="frame"))
        write_video(Path(args.video), frames, seq.fps or 25.0)
        print(f"{n} frames -> {args.video}")
    return 0


COMMANDS = {"convert": cmd_convert, "synth": cmd_synth, "show": cmd_show, "demo": cmd_demo}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
