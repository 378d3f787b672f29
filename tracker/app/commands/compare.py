"""``pose-tracker compare``: run an experiment: priors x sequences x settings x seeds, with tables."""
from __future__ import annotations

import argparse
import logging
import shlex
from pathlib import Path
from typing import Sequence

from tracker.app.backends import EXECUTION_OPTIONS
from tracker.app.console import close_bars, interrupted_status, invoked_as, shows_progress
from tracker.app.schema import add_option_flags

log = logging.getLogger(__name__)

NAME = "compare"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    e = sub.add_parser("compare", parents=parents,
                       help="run an experiment: priors x sequences x settings x seeds, with tables",
                       description="Run every configuration of an experiment file (TOML; see "
                                   "tracker/app/experiment.py and benchmarks/experiments/) in parallel, skipping "
                                   "runs finished before, and write table.md, table.csv, per_frame.png and "
                                   "report.html (one self-contained page: the tables, the plot and overlay "
                                   "videos).")
    e.add_argument("experiment", metavar="EXPERIMENT", help="experiment file (.toml)")
    e.add_argument("--out", required=True,
                   help="output folder (runs, cached sequences and models, tables); an earlier compare output "
                        "is continued (finished runs are skipped)")
    e.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty output folder that is not a compare output")
    add_option_flags(e, EXECUTION_OPTIONS, {"jobs": "JOBS", "address": "ADDRESS"})
    e.add_argument("--data-root", default=None, metavar="DIR",
                   help="folder the experiment's data paths are relative to, in place of the file's data_root "
                        "(default: $POSE_TRACKER_DATA_ROOT, else the file's data_root)")
    e.add_argument("--no-videos", dest="videos", action="store_false",
                   help="leave out report.html's overlay videos of the best and the worst prior (a few seconds "
                        "each: one per sequence and view set)")
    return e


def run(args: argparse.Namespace) -> int:
    from tracker.app.compare import compare, finished_runs

    command = shlex.join([*invoked_as().split(), *args.argv])  # as typed, recorded in report.html
    try:
        summary = compare(args.experiment, args.out, **{o.name: getattr(args, o.name) for o in EXECUTION_OPTIONS},
                          threads=args.threads, data_root=args.data_root, overwrite=args.overwrite,
                          videos=args.videos, progress=shows_progress(), command=command)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: every finished run is kept, and the same command continues
        close_bars()
        done, total = finished_runs(args.out)
        kept = f"{done} of {total} runs finished and kept" if total else "nothing run yet"
        log.warning(f"interrupted: {kept} in {args.out}; continue with: {command}")
        return interrupted_status()
    print(summary["table"])
    log.info(f"-> {Path(args.out) / 'table.md'}, table.csv, per_frame.png, report.html")
    return 0
