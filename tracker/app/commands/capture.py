"""``pose-tracker capture``: calibrated videos in, tracked poses out: every step in one command."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.person_segmentation import INSTALL as SEGMENTATION_INSTALL
from tracker.app.commands.arguments import downscale_type
from tracker.core.errors import InputError

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
    c.add_argument("--views", metavar="LIST",
                   help="cameras to use, as indices into the calibration's (e.g. 0,2 or 1 alone; default all)")
    c.add_argument("--prior", default=None, metavar="NAME", help="motion prior (default mixture: the shipped "
                                                                 "neural prior with zero-velocity)")
    c.add_argument("--particles", type=int, default=None, metavar="N", help="particles (default 1000)")
    c.add_argument("--seed", type=int, default=0, help="random seed of the tracking (default 0)")
    c.add_argument("--downscale", type=downscale_type, default=None, metavar="F",
                   help="shrink every frame by F before everything else (default 4)")
    c.add_argument("--frames", metavar="A:B", help="video frames A to B-1 (default: all the videos share)")
    c.add_argument("--overwrite", action="store_true",
                   help="start again in a folder holding a capture of other videos or views")
    return c


def run(args: argparse.Namespace) -> int:
    from tracker.app.capture import DEFAULT_DOWNSCALE, DEFAULT_PARTICLES, DEFAULT_PRIOR, STEPS, capture

    views = None
    if args.views is not None:
        try:
            views = [int(v) for v in args.views.split(",") if v.strip()]
        except ValueError:
            raise InputError(f"--views must be comma-separated camera indices, got {args.views!r}") from None
    if args.particles is not None and args.particles < 1:
        raise InputError(f"--particles must be at least 1, got {args.particles}")
    done = []

    def on_step(step: str, line: str) -> None:
        done.append(step)
        log.info(f"[{len(done)}/{len(STEPS)}] {step}: {line}")

    result = capture(args.videos, args.calibration, args.out, views=views, prior=args.prior or DEFAULT_PRIOR,
                     seed=args.seed, particles=args.particles or DEFAULT_PARTICLES,
                     downscale=args.downscale or DEFAULT_DOWNSCALE, frames=args.frames, overwrite=args.overwrite,
                     on_step=on_step)
    print(", ".join(sorted(p.name for p in result.files.values() if p.is_file())) + f" -> {result.out}")
    return 0
