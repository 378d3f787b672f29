"""``pose-tracker capture``: calibrated videos in, tracked poses out: every step in one command."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.vision.person_segmentation import INSTALL as SEGMENTATION_INSTALL
from tracker.app.capture import CAPTURE_OPTIONS
from tracker.app.schema import add_option_flags

log = logging.getLogger(__name__)

NAME = "capture"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    c = sub.add_parser("capture", parents=parents,
                       help="calibrated videos in, tracked poses out: every step in one command",
                       description="Import the videos, write the person's silhouettes, detect 2-D keypoints, "
                                   "fit the body's size and first poses to them, track with the recommended "
                                   "prior and the keypoint and silhouette likelihoods, and write OUT/poses.trc, "
                                   "OUT/poses.bvh, OUT/triangulated.trc (the keypoints triangulated, with two "
                                   "or more views), OUT/overlay.mp4 and OUT/result.json. A rerun skips the "
                                   "steps already done. Needs MediaPipe (" + SEGMENTATION_INSTALL + ").")
    c.add_argument("videos", nargs="+", metavar="VIDEO", help="one video file per camera, paired by sorted name")
    c.add_argument("--calibration", required=True, metavar="FILE", help="the cameras' calibration file")
    c.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_option_flags(c, CAPTURE_OPTIONS, {"views": "LIST", "prior": "NAME", "particles": "N", "downscale": "F",
                                         "frames": "A:B"})
    c.add_argument("--overwrite", action="store_true",
                   help="start again in a folder holding a capture of other videos or views")
    return c


def run(args: argparse.Namespace) -> int:
    from tracker.app.capture import STEPS, capture

    done = []

    def on_step(step: str, line: str) -> None:
        done.append(step)
        log.info(f"[{len(done)}/{len(STEPS)}] {step}: {line}")

    result = capture(args.videos, args.calibration, args.out, overwrite=args.overwrite, on_step=on_step,
                     **{o.name: getattr(args, o.name) for o in CAPTURE_OPTIONS})
    print(", ".join(sorted(p.name for p in result.files.values() if p.is_file())) + f" -> {result.out}")
    return 0
