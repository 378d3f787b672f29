"""Split each row's marker error into root height, rest of the root, and body (run by hand).

    python benchmarks/error_split.py RESULTS/leave_out_16 RESULTS/leave_out_91 ... [--baseline zero-velocity]

For every folder `compare` wrote and every prior row and view count in it (training seeds pooled, as in its
table): the mean marker error over the runs (mm), the same error with each frame's root height error taken out of
the estimate's markers (the estimate moved vertically so that its root is at the true height), with its whole root
translation error taken out (the pelvis-relative error), and the mean signed root height error (mm, estimate minus
truth); each error also as a ratio to the baseline's (same folder, same views). Reads each run's
``result.json`` and ``estimates.npz`` and the sequence's ground truth. Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np


def split(run: Path) -> tuple[str, int, np.ndarray]:
    """(row label without training seed and views, view count, [marker, height removed, root removed, root height
    error]) of one run folder."""
    result = json.loads((run / "result.json").read_text())
    row = result["run"]["row"]
    label = (row.rpartition(", views ")[0] or row).split(", training seed")[0]
    estimates = np.load(run / "estimates.npz")
    truth = np.load(Path(result["sequence"]) / "groundtruth.npz")
    frames = np.asarray(result["tracked_frames"])
    est, true = estimates["markers"][frames], truth["markers"][frames]  # T x 15 x 3, mm
    root_error = estimates["poses"][frames, :3] - truth["poses"][frames, :3]  # T x 3, mm
    height_only = np.zeros_like(root_error)
    height_only[:, 2] = root_error[:, 2]

    def mean_error(shift: np.ndarray) -> float:
        return float(np.linalg.norm(est - shift[:, None] - true, axis=2).mean())
    return label, len(result["views"]), np.array([mean_error(np.zeros_like(root_error)), mean_error(height_only),
                                                  mean_error(root_error), float(root_error[:, 2].mean())])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+")
    parser.add_argument("--baseline", default="zero-velocity")
    args = parser.parse_args()
    print("| folder | prior | views | marker (ratio) | root height removed | whole root removed | root height error |")
    print("|---|---|---|---|---|---|---|")
    for folder in args.folders:
        rows: dict[tuple[str, int], list[np.ndarray]] = defaultdict(list)
        for run in sorted((folder / "runs").glob("*/result.json")):
            label, views, values = split(run.parent)
            rows[(label, views)].append(values)
        means = {key: np.mean(values, axis=0) for key, values in rows.items()}
        for (label, views), m in sorted(means.items(), key=lambda kv: (-kv[0][1], kv[0][0])):
            base = means.get((args.baseline, views))
            cells = [f"{m[i]:.1f}" + (f" ({m[i] / base[i]:.2f})" if base is not None else "") for i in range(3)]
            print(f"| {folder.name} | {label} | {views} | " + " | ".join(cells) +
                  f" | {m[3]:+.1f} ({len(rows[(label, views)])} runs) |")


if __name__ == "__main__":
    main()
