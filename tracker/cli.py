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


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


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


COMMANDS = {"convert": cmd_convert, "demo": cmd_demo}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
