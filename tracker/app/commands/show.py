"""``pose-tracker show``: draw the projected body model over every view of a sequence frame."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.io.files import check_output_file
from tracker.app.commands.arguments import non_negative_int
from tracker.app.console import progress_bar
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

NAME = "show"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    w = sub.add_parser("show", parents=parents,
                       help="draw the projected body model over every view of a sequence frame",
                       description="Draw the projected cones (ground truth, the initial pose, or --poses) over "
                                   "every camera view in one grid image, or a whole sequence as a video.")
    w.add_argument("sequence", metavar="DIR", help="sequence folder (own layout or PARSEC bodytrack)")
    w.add_argument("--frame", type=non_negative_int, default=0, help="frame to draw (default 0)")
    w.add_argument("--poses", help="estimates.npz (poses T x D) to draw instead of the ground truth")
    w.add_argument("--out", help="output image (.png)")
    w.add_argument("--video", help="also write every frame to this video (.mp4)")
    w.add_argument("--overwrite", action="store_true", help="replace existing files at --out and --video")
    return w


def run(args: argparse.Namespace) -> int:
    from tracker.app.api import show

    if not args.out and not args.video:
        raise InputError("nothing to write: give --out FILE.png and/or --video FILE.mp4")
    if args.out:
        check_output_file(args.out, "--out", (".png",), new=not args.overwrite)
    if args.video:
        check_output_file(args.video, "--video", (".mp4",), new=not args.overwrite)
    written = show(args.sequence, frame=args.frame, poses=args.poses, out=args.out, video=args.video,
                   progress=lambda it: progress_bar(it, desc="video", unit="frame"))
    for line in written:
        log.info(line)
    return 0
