"""``pose-tracker demo``: render, track and score a shipped walk: a first run that needs no data of your own."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Sequence

from tracker.app.commands.arguments import number_type

log = logging.getLogger(__name__)

NAME = "demo"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    d = sub.add_parser("demo", parents=parents,
                       help="render, track and score a shipped walk: a first run that needs no data of your own",
                       description="Render 1.5 s of the shipped CMU walk 07_01 (subject 7) into 4 cameras, "
                                   "track it with the zero-velocity prior and with the recommended default, the "
                                   "mixture of the pretrained neural prior (which never saw subject 7) and "
                                   "zero-velocity, 1000 particles, tracking seeds 0, 1 and 2 each (nothing is "
                                   "trained), print every run's errors and one line saying what they show, and "
                                   "write the error-per-frame plot and an overlay video.")
    d.add_argument("--out", default="demo_output",
                   help="output folder (default ./demo_output); a folder holding an earlier demo's output (its "
                        "demo.json) is replaced whole only with --overwrite, and a non-empty folder without it never")
    d.add_argument("--overwrite", action="store_true", help="replace an earlier demo's output at --out")
    d.add_argument("--frames", type=number_type(int, 4, strict=False), default=90,
                   help="frames to render and track (default 90: 1.5 s)")
    return d


def run(args: argparse.Namespace) -> int:
    from tracker.app.demo import run_demo

    return run_demo(Path(args.out), args.frames, overwrite=args.overwrite)
