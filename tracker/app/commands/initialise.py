"""``pose-tracker initialise``: fit the body's size and first poses to a sequence's keypoints or first silhouettes."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence


log = logging.getLogger(__name__)

NAME = "initialise"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    i = sub.add_parser("initialise", parents=parents,
                       help="fit the body's size and first poses to a sequence's keypoints or first silhouettes",
                       description="For a sequence with keypoints (pose-tracker keypoints): measure the body's "
                                   "limbs from the keypoints triangulated over the views and fit the first "
                                   "poses' 40 numbers to the keypoints in every view (one view: the default "
                                   "body, placed by its height in the image). Otherwise: search the floor position, "
                                   "heading, body scale and stance (standing, "
                                   "A-pose, T-pose; or around --near, an approximate pose of your own) that the "
                                   "tracker's likelihood rates best on the first frame's silhouettes, refine "
                                   "every pose number from both headings (silhouettes hardly tell front from "
                                   "back), write the fitted body shape into the sequence's "
                                   "meta.json (which track then uses) and the first poses to --out, for track "
                                   "--init. --proportions landmarks measures the person's upper arms, forearms, "
                                   "thighs and shanks from BlazePose's landmarks triangulated over the first "
                                   "frames' views and keeps that body instead of searching the scale.")
    i.add_argument("sequence", metavar="DIR", help="sequence folder with silhouettes (masks/) or plates")
    i.add_argument("--out", required=True, metavar="FILE", help="poses file to write (.npz, for track --init)")
    i.add_argument("--overwrite", action="store_true", help="replace an existing poses file at --out")
    i.add_argument("--near", metavar="POSES.npz", help="an approximate first pose to search around")
    i.add_argument("--frames", type=int, default=2, metavar="N",
                   help="how many first frames the pose is written for (track's --known-frames; default 2)")
    i.add_argument("--seed", type=int, default=0, help="random seed of the local search (default 0)")
    i.add_argument("--evidence", choices=("keypoints", "silhouettes"), default=None,
                   help="what the start is fitted to: keypoints (the default for a sequence with keypoints: the "
                        "body measured from the keypoints triangulated over the views, the pose fitted to them) "
                        "or silhouettes (the default otherwise: the search described above)")
    i.add_argument("--proportions", choices=("scale", "landmarks"), default="scale",
                   help="scale: the default adult's proportions at the scale the silhouettes fit best "
                        "(default); landmarks: the person's own segment lengths, measured from BlazePose's "
                        "landmarks triangulated over the first frames' views (needs the package silhouettes "
                        "--method person needs)")
    return i


def run(args: argparse.Namespace) -> int:
    from tracker.app.preparation import initialise_sequence

    start = initialise_sequence(args.sequence, args.out, evidence=args.evidence, near=args.near,
                                proportions=args.proportions, frames=args.frames, seed=args.seed,
                                overwrite=args.overwrite, overwrite_flag="--overwrite")
    for line in start.lines:
        log.info(line)
    print(f"{start.summary} -> {args.out}; body shape -> {start.meta_file}")
    return 0
