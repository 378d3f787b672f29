"""Where the tracker loses a person who starts walking from standing: per prior and view set, at a few frames,
the person's ground speed, the marker error, how far the estimated pelvis is from the person's on the ground, and
how far the estimated torso (pelvis to thorax) leans from vertical beside the person's.

    python benchmarks/start_from_standing.py RESULTS_DIR SEQUENCE_DIR [--frames 30,60,90,120,149]

RESULTS_DIR is a ``compare`` output folder (its ``runs/*/`` hold ``result.json`` and ``estimates.npz``);
only its runs on SEQUENCE_DIR are read. Numbers are means over the tracking seeds.
"""
from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np

PELVIS, THORAX = 0, 1  # marker indices (tracker.core.body.MARKER_NAMES)


def lean_degrees(markers: np.ndarray) -> np.ndarray:
    """Angle (degrees) between the pelvis-to-thorax vector and the vertical, per frame, markers ``T x 15 x 3``."""
    v = markers[:, THORAX] - markers[:, PELVIS]
    return np.degrees(np.arccos(np.clip(v[:, 2] / np.linalg.norm(v, axis=1), -1.0, 1.0)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("sequence", type=Path)
    ap.add_argument("--frames", default="30,60,90,120,149")
    args = ap.parse_args()
    frames = [int(f) for f in args.frames.split(",")]
    truth = np.load(args.sequence / "groundtruth.npz")
    gt_markers, fps = truth["markers"], float(truth["fps"])
    speed = np.r_[0.0, np.linalg.norm(np.diff(truth["poses"][:, :2], axis=0), axis=1)] * fps / 1000.0
    speed = np.convolve(speed, np.ones(15) / 15, mode="same")  # m/s, smoothed over a quarter second
    rows: dict[tuple, list] = defaultdict(list)
    for run in sorted(args.results.glob("runs/*/result.json")):
        result = json.loads(run.read_text())
        if Path(result["sequence"]).resolve() != args.sequence.resolve():
            continue
        est = np.load(run.parent / "estimates.npz")["markers"]
        n = min(len(est), len(gt_markers))
        key = (result["prior"], Path(result["prior_models"][0]).stem if result["prior_models"] else "",
               " ".join(f"{k}={v}" for k, v in sorted(result["prior_options"].items())),
               ",".join(map(str, result["views"])))
        err = np.linalg.norm(est[:n] - gt_markers[:n], axis=2).mean(axis=1)
        pelvis = np.linalg.norm(est[:n, PELVIS, :2] - gt_markers[:n, PELVIS, :2], axis=1)
        rows[key].append((err, pelvis, lean_degrees(est[:n])))
    lean_gt = lean_degrees(gt_markers)
    print("person: " + ", ".join(f"frame {f} {speed[f]:.2f} m/s lean {lean_gt[f]:.0f} deg" for f in frames))
    print("prior | model | options | views | " + " | ".join(f"frame {f}: error, pelvis off, lean" for f in frames))
    for key, runs in sorted(rows.items()):
        err, pelvis, lean = (np.mean([r[i] for r in runs], axis=0) for i in range(3))
        print(" | ".join(key) + " | " + " | ".join(f"{err[f]:.0f} mm, {pelvis[f]:.0f} mm, {lean[f]:.0f} deg"
                                                for f in frames if f < len(err)))


if __name__ == "__main__":
    main()
