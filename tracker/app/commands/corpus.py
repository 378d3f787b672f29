"""``pose-tracker corpus``: list what a mocap corpus holds: clips, frames, rates, labels, conventions, refused files."""
from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path
from typing import Sequence

log = logging.getLogger(__name__)

NAME = "corpus"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    k = sub.add_parser("corpus", parents=parents, help="list what a mocap corpus holds: clips, frames, rates, "
                                                             "labels, conventions, refused files",
                       description="Read every mocap file that the paths name (files; folders, searched "
                                   "recursively; glob patterns such as 'bandai2/*walk*.bvh') as train reads it, and "
                                   "list each clip's frames, rate, duration, skeleton naming convention, length "
                                   "unit, up axis and labels, then every refused file with its reason (all of "
                                   "them, not the first only) and a total line. Exit status 2 when a file is "
                                   "refused.")
    k.add_argument("paths", nargs="+", metavar="PATH_OR_GLOB", help="mocap files, folders or glob patterns")
    k.add_argument("--labels", metavar="PATTERN|FILE",
                   help="labels per clip: a pattern over file names such as 'dataset-2_{content}_{style}_{take}' "
                        "({key} matches a label, {} anything), or a CSV, TOML or JSON file mapping files to labels")
    k.add_argument("--json", action="store_true", help="print one JSON document (clips, refused, total) instead")
    return k


def _shown(path: str) -> str:
    """``path`` relative to the working folder where it lies below it, else as it is."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return path


def run(args: argparse.Namespace) -> int:
    from data_tools.motion.corpus import survey, survey_totals
    entries = survey(args.paths, args.labels)
    clips = [e for e in entries if e.refused is None]
    refused = [e for e in entries if e.refused is not None]
    totals = survey_totals(entries)
    if args.json:
        print(json.dumps({"clips": [{**e.as_dict(), "file": _shown(e.path)} for e in clips],
                          "refused": [{"file": _shown(e.path), "reason": e.refused} for e in refused],
                          "total": totals.as_dict()}, indent=1))
        return 2 if refused else 0
    rows = [(_shown(e.path), str(e.frames), f"{e.fps:g}", f"{e.seconds:.1f}", e.naming, e.unit, e.up,
             " ".join(f"{k}={v}" for k, v in e.labels.items())) for e in clips]
    head = ("file", "frames", "Hz", "seconds", "naming", "length unit", "up", "labels")
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
    for row in [head, *rows]:
        print("  ".join(c.rjust(w) if i in (1, 2, 3) else c.ljust(w)
                        for i, (c, w) in enumerate(zip(row, widths))).rstrip())
    for e in refused:
        print(f"refused {_shown(e.path)}: {e.refused}")
    by_rate = ", ".join(f"{n} at {r:g} Hz" for r, n in totals.rates.items())
    print(f"total: {totals.clips} clip(s), {totals.frames} frames, {totals.seconds / 60:.1f} min "
          f"({by_rate or 'none'}); {totals.refused} refused")
    return 2 if refused else 0
