"""``pose-tracker silhouettes``: write the person's silhouettes of a sequence that has no background plate."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.vision.person_segmentation import INSTALL as SEGMENTATION_INSTALL

log = logging.getLogger(__name__)

NAME = "silhouettes"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    m = sub.add_parser("silhouettes", parents=parents,
                       help="write the person's silhouettes of a sequence that has no background plate",
                       description="Write masks/<camera>/NNNNNN.png, which track then uses. --method median "
                                   "learns each camera's background from the sequence's own frames (the "
                                   "per-pixel median of up to 25 frames) and subtracts it: it needs a person who "
                                   "moves. --method person runs a person-segmentation model (MediaPipe's "
                                   f"BlazePose, an optional package: {SEGMENTATION_INSTALL}) and "
                                   "finds a person who stands still too. Either keeps the largest region. Masks "
                                   "of your own go in masks/<camera>/ (non-zero = person, one PNG per frame, "
                                   "named as the images).")
    m.add_argument("sequence", metavar="DIR", help="sequence folder (e.g. written by import-video)")
    m.add_argument("--method", choices=("median", "person"), default=None,
                   help="median: background learnt from the frames (a person who moves); person: a "
                        "person-segmentation model (a person who may stand still). Default: person where "
                        "MediaPipe is installed and finds a person in every camera's first frame, else median")
    m.add_argument("--overwrite", action="store_true", help="replace masks/ where the sequence has it")
    return m


def run(args: argparse.Namespace) -> int:
    from tracker.app.preparation import write_silhouettes

    written = write_silhouettes(args.sequence, args.method, overwrite=args.overwrite, overwrite_flag="--overwrite")
    for cam, share in zip(written.cameras, written.person_share):
        log.info(f"{cam}: the person covers {100 * share:.1f}% of the image on average")
    print(f"{len(written.cameras)} cameras x {written.frames} frames of silhouettes ({written.method}) -> "
          f"{written.root / 'masks'}")
    return 0
