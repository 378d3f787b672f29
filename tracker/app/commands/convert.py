"""``pose-tracker convert``: convert a mocap clip (AMC+ASF or BVH) to body-model poses and markers."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Sequence

from data_tools.io.files import atomic_path, check_not_inside, check_output_file
from tracker.app.commands.arguments import JOINT_MAP_HELP, fps_type, length_unit_type

log = logging.getLogger(__name__)

NAME = "convert"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    c = sub.add_parser("convert", parents=parents,
                       help="convert a mocap clip (AMC+ASF or BVH) to body-model poses and markers",
                       description="Retarget a mocap clip to the 15-cone body model and write CLIP.npz with "
                                   "poses, markers (ground truth), model_markers, fps and the body shape.")
    c.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    c.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    c.add_argument("--fps", type=fps_type, default=None,
                   help="output frame rate in Hz (default: the file's own); other rates are interpolated")
    c.add_argument("--joint-map", metavar="FILE", help=JOINT_MAP_HELP)
    c.add_argument("--length-unit", type=length_unit_type, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred from the skeleton's height)")
    c.add_argument("--out", required=True, help="output .npz")
    c.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    return c


def run(args: argparse.Namespace) -> int:
    from data_tools.motion.clip_io import save_converted_clip
    from tracker.app.api import read_clip

    out = check_output_file(args.out, "the output", (".npz",), new=not args.overwrite)
    check_not_inside(out, {"mocap file": args.mocap, **({"skeleton": args.skeleton} if args.skeleton else {})})
    clip, result = read_clip(args.mocap, args.skeleton, args.fps, args.length_unit, args.joint_map)
    with atomic_path(out) as tmp:
        save_converted_clip(result, tmp)
    print(f"{Path(args.mocap).name}: {clip.summary()}; {len(result.poses)} frames at {result.fps:g} fps, "
          f"mean retarget residual {result.mean_residual:.2f} mm -> {out}")  # the residual: how well it went
    return 0
