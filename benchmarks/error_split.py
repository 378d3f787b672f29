"""Split each row's marker error into root height, rest of the root, and body (run by hand).

    python benchmarks/error_split.py RESULTS/leave_out_16 RESULTS/leave_out_91 ... [--baseline zero-velocity]

For every folder `compare` wrote and every row of its grid (prior, views, particles, layers; training seeds
pooled, as in its table): the mean marker error over the runs (mm); the same error with each frame's root height
error taken out of the estimate's markers (the estimate moved vertically so that its root is at the true height);
with its whole root translation error taken out (the pelvis-relative error); and the mean signed root height error
(mm, estimate minus truth). Each error also as a ratio to the baseline's (same folder, views, particles and
layers). Reads each run's ``result.json`` and ``estimates.npz`` and the sequence's ground truth. Prints a Markdown
table.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tracker.core.metrics import marker_error  # noqa: E402


#: The grid axes that :func:`tracker.app.experiment.row_label` appends to a prior's label.
AXES = re.compile(r"(, (views [\d,]+|all views|\d+ particles?|\d+ layers?))+$")


def split(run: Path) -> tuple[tuple[str, str, int, int], np.ndarray]:
    """(row: prior label without training seed, views, particles, layers; [marker, height removed, root removed,
    root height error]) of one run folder."""
    result = json.loads((run / "result.json").read_text())
    spec = result["run"]
    label = AXES.sub("", re.sub(r", training seed \d+", "", spec["row"]))
    views = "all" if spec["views"] is None else ",".join(map(str, spec["views"]))
    row = (label, views, int(spec["particles"]), int(spec["annealing_layers"]))
    estimates = np.load(run / "estimates.npz")
    truth = np.load(Path(result["sequence"]) / "groundtruth.npz")
    frames = np.asarray(result["tracked_frames"])
    est, true = estimates["markers"][frames], truth["markers"][frames]  # T x 15 x 3, mm
    root_error = estimates["poses"][frames, :3] - truth["poses"][frames, :3]  # T x 3, mm
    height_only = np.zeros_like(root_error)
    height_only[:, 2] = root_error[:, 2]

    def mean_error(shift: np.ndarray) -> float:
        return float(marker_error(est - shift[:, None], true).mean())
    return row, np.array([mean_error(np.zeros_like(root_error)), mean_error(height_only), mean_error(root_error),
                          float(root_error[:, 2].mean())])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--baseline", default="zero-velocity")
    args = parser.parse_args()
    print("| folder | prior | views | particles x layers | marker (ratio) | root height removed | whole root removed "
          "| root height error |")
    print("|---|---|---|---|---|---|---|---|")
    for folder in args.folders:
        rows: dict[tuple[str, str, int, int], list[np.ndarray]] = defaultdict(list)
        for run in sorted((folder / "runs").glob("*/result.json")):
            row, values = split(run.parent)
            rows[row].append(values)
        means = {row: np.mean(values, axis=0) for row, values in rows.items()}
        for row, m in sorted(means.items(), key=lambda kv: (-len(kv[0][1]), kv[0][1:], kv[0][0])):
            label, views, particles, layers = row
            base = means.get((args.baseline, views, particles, layers))
            cells = [f"{m[i]:.1f}" + (f" ({m[i] / base[i]:.2f})" if base is not None else "") for i in range(3)]
            print(f"| {folder.name} | {label} | {views} | {particles} x {layers} | " + " | ".join(cells) +
                  f" | {m[3]:+.1f} ({len(rows[row])} runs) |")


if __name__ == "__main__":
    main()
