"""Summarise the leave-one-subject-out folds (issue 13's targets) from the folders `compare` wrote.

    python benchmarks/loso_summary.py RESULTS/leave_out_02 RESULTS/leave_out_07 ... [--baseline zero-velocity]

For every prior row and view set: each fold's marker error as a ratio to the baseline's (same fold, same
views), their mean over the folds, and the worst fold; rows missing from a fold are left out of its mean and
the fold count says so. Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path


def read_fold(folder: Path) -> dict[tuple[str, str], float]:
    """(prior label, views) -> mean marker error (mm) of one fold's table.csv (one sequence per fold)."""
    out = {}
    with open(folder / "table.csv", newline="") as f:
        for row in csv.DictReader(f):
            if row["metric"] != "mean_error_mm":
                continue
            label, _, views = row["row"].rpartition(", views ")
            out[(label, views)] = float(row["mean"])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--baseline", default="zero-velocity")
    args = parser.parse_args()
    folds = {f.name: read_fold(f) for f in args.folders}
    ratios: dict[tuple[str, str], dict[str, float]] = defaultdict(dict)
    for name, table in folds.items():
        for (label, views), err in table.items():
            base = table.get((args.baseline, views))
            if base:
                ratios[(label, views)][name] = err / base
    names = list(folds)
    print("| prior | views | " + " | ".join(names) + " | mean ratio | worst | folds |")
    print("|---|---|" + "---|" * (len(names) + 3))
    for (label, views), by_fold in sorted(ratios.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        if label == args.baseline:
            continue
        cells = [f"{folds[n][(label, views)]:.1f} ({by_fold[n]:.2f})" if n in by_fold else "" for n in names]
        values = list(by_fold.values())
        print(f"| {label} | {views} | " + " | ".join(cells) +
              f" | {sum(values) / len(values):.2f} | {max(values):.2f} | {len(values)}/{len(names)} |")
    base_cells = {v: [f"{folds[n].get((args.baseline, v), float('nan')):.1f}" for n in names]
                  for v in sorted({v for t in folds.values() for (_, v) in t})}
    for views, cells in base_cells.items():
        print(f"| {args.baseline} (mm) | {views} | " + " | ".join(cells) + " | 1 | 1 | |")


if __name__ == "__main__":
    main()
