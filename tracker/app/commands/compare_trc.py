"""``pose-tracker compare-trc``: compare a tracked run with a reference reconstruction in a TRC file."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence


log = logging.getLogger(__name__)

NAME = "compare-trc"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    r = sub.add_parser("compare-trc", parents=parents,
                       help="compare a tracked run with a reference reconstruction in a TRC file",
                       description="Map the reference's keypoints to the body model's markers (Pose2Sim / "
                                   "OpenPose names: thorax = Neck, head = Head, and the limbs' joints; the pelvis "
                                   "is left out), align the whole estimate to the reference with one "
                                   "rigid transform, and print the mean distance per joint and overall (mm). The "
                                   "reference's keypoints are not the model's markers (a hip keypoint is not "
                                   "the hip joint centre): the distances include that difference.")
    r.add_argument("run", metavar="RUN", help="a folder written by track (estimates.npz)")
    r.add_argument("reference", metavar="TRC", help="reference reconstruction (.trc)")
    r.add_argument("--offset", type=int, default=None, metavar="N",
                   help="reference frame of the estimate's first frame (default: the first video frame the "
                        "sequence was imported from, else 0)")
    return r


def run(args: argparse.Namespace) -> int:
    from tracker.app.exporting import compare_run_to_trc

    print(compare_run_to_trc(args.run, args.reference, offset=args.offset).table())
    return 0
