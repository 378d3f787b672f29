"""Each prior's marker error as a ratio to the baseline's, over the folders `compare` wrote (one or more folds).

    python benchmarks/loso_summary.py RESULTS/leave_out_02 RESULTS/leave_out_07 ... [--baseline zero-velocity]

For every prior row and view set: its marker error on each fold's sequence (one column per folder and
sequence) as a ratio to the baseline's (same sequence, same views), the mean of the ratios over the columns,
and the worst; a row missing from a column is left out of its mean and the count says so. Prints a Markdown
table.
"""
from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path


def read_fold(folder: Path) -> dict[str, dict[tuple[str, str], float]]:
    """Sequence -> (prior label, views) -> mean marker error (mm), from one folder's table.csv (rows without
    a view set, from experiments with one, get views "all")."""
    out: dict[str, dict[tuple[str, str], float]] = defaultdict(dict)
    with open(folder / "table.csv", newline="") as f:
        for row in csv.DictReader(f):
            if row["metric"] not in ("mpjpe_abs", "mean_error_mm"):  # the latter in folders of versions before 0.16
                continue
            label, sep, views = row["row"].rpartition(", views ")
            if not sep:
                label, views = row["row"], "all"
            out[row["sequence"]][(label, views)] = float(row["mean"])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--baseline", default="zero-velocity")
    args = parser.parse_args()
    columns: dict[str, dict[tuple[str, str], float]] = {}  # one column per (folder, sequence)
    for folder in args.folders:
        for sequence, table in read_fold(folder).items():
            name = f"{folder.name}: {sequence}"
            if name in columns:
                raise SystemExit(f"{folder}: a second folder named {folder.name} with sequence {sequence!r}")
            columns[name] = table
    ratios: dict[tuple[str, str], dict[str, float]] = defaultdict(dict)
    for name, table in columns.items():
        for (label, views), err in table.items():
            base = table.get((args.baseline, views))
            if base:
                ratios[(label, views)][name] = err / base
    names = list(columns)
    print("| prior | views | " + " | ".join(names) + " | mean ratio | worst | columns |")
    print("|---|---|" + "---|" * (len(names) + 3))
    for (label, views), by_col in sorted(ratios.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        if label == args.baseline:
            continue
        cells = [f"{columns[n][(label, views)]:.1f} ({by_col[n]:.2f})" if n in by_col else "" for n in names]
        values = list(by_col.values())
        print(f"| {label} | {views} | " + " | ".join(cells) +
              f" | {sum(values) / len(values):.2f} | {max(values):.2f} | {len(values)}/{len(names)} |")
    for views in sorted({v for t in columns.values() for (_, v) in t}):
        cells = [f"{columns[n][(args.baseline, views)]:.1f}" if (args.baseline, views) in columns[n] else ""
                 for n in names]
        print(f"| {args.baseline} (mm) | {views} | " + " | ".join(cells) + " | 1 | 1 | |")


if __name__ == "__main__":
    main()
