"""``pose-tracker export``: write a tracked run's poses as BVH and/or TRC."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence


log = logging.getLogger(__name__)

NAME = "export"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    x = sub.add_parser("export", parents=parents, help="write a tracked run's poses as BVH and/or TRC",
                       description="Write the poses of a tracked run (its folder, with result.json and "
                                   "estimates.npz) as BVH (a skeleton of the body model's links; y up, --unit, "
                                   "default metres: Blender's importer reads it at life size) and/or TRC (the 15 "
                                   "markers, y up, metres, OpenSim's and Pose2Sim's axes: TRC X, Y, Z = our y, "
                                   "z, x).")
    x.add_argument("run", metavar="RUN", help="a folder written by track (result.json, estimates.npz)")
    x.add_argument("--bvh", metavar="FILE", help="write the poses as BVH here (.bvh)")
    x.add_argument("--trc", metavar="FILE", help="write the markers as TRC here (.trc)")
    x.add_argument("--unit", choices=("m", "cm", "mm"), default="m", help="BVH length unit (default m)")
    x.add_argument("--overwrite", action="store_true", help="replace existing files at --bvh and --trc")
    x.add_argument("--sequence", metavar="DIR",
                   help="the tracked sequence (default: the one result.json names; its body shape is used)")
    return x


def run(args: argparse.Namespace) -> int:
    from tracker.app.exporting import export_run

    export_run(args.run, bvh=args.bvh, trc=args.trc, unit=args.unit, sequence=args.sequence, overwrite=args.overwrite,
               overwrite_flag="--overwrite", on_written=print)
    return 0
