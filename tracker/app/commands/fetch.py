"""``pose-tracker fetch``: download CMU mocap trials into a data root, checked."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from tracker.app.commands.arguments import positive_float

log = logging.getLogger(__name__)

NAME = "fetch"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    f = sub.add_parser("fetch", parents=parents, help="download CMU mocap trials into a data root, checked",
                       description="Download CMU motion capture trials (and their subjects' skeletons) from the "
                                   "CMU database (http://mocap.cs.cmu.edu) or a mirror into DATA_ROOT/mocap/cmu/"
                                   "<subject>/, where experiment files look for them. Each file is checked by "
                                   "parsing it (skeleton bones and lengths, the trial's frame count) before it is "
                                   "put in place; files already there that pass the check are not downloaded "
                                   "again.")
    f.add_argument("dataset", nargs="?", metavar="cmu",
                   help="the database, the only one, which may be left out: 'fetch 07_01' is 'fetch cmu 07_01'")
    f.add_argument("trials", nargs="*", metavar="TRIAL", help="CMU trials as SUBJECT_TRIAL, e.g. 07_01 16_15")
    f.add_argument("--for", dest="experiment", default=None, metavar="EXPERIMENT",
                   help="also every CMU trial this experiment file (.toml) names, into its data root")
    f.add_argument("--data-root", default=None, metavar="DIR",
                   help="folder to place the files under (default: $POSE_TRACKER_DATA_ROOT, else the experiment "
                        "file's data_root)")
    f.add_argument("--mirror", default=None, metavar="URL",
                   help="base URL of a copy laid out as http://mocap.cs.cmu.edu/subjects (URL/07/07_01.amc)")
    f.add_argument("--timeout", type=positive_float, default=30.0,
                   help="seconds to wait for the server (default 30)")
    return f


def run(args: argparse.Namespace) -> int:
    from tracker.app.fetching import fetch

    trials = args.trials if args.dataset in (None, "cmu") else [args.dataset, *args.trials]  # `fetch 07_01`
    fetch(trials, experiment=args.experiment, data_root=args.data_root, mirror=args.mirror, timeout=args.timeout)
    return 0
