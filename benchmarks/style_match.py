"""How often a style-inferring prior's most probable label is the true activity (the activity-switch target: 80%), from
the runs an experiment wrote. Run by hand:

    python benchmarks/style_match.py RESULTS/activity_switch [--sequence "subject 16 walk then run"]
        [--schedule walk,run@120] [--skip 10] [--fade 12]

For every run of the sequence whose prior reports a posterior over labels (``prior_summary`` in result.json),
the fraction of tracked frames whose most probable label is the schedule's, leaving out the first ``--skip``
frames of each segment (the tracked start, and the switch) and the ``--fade`` frames of the cross-fade before
the switch. Prints one Markdown row per prior row (views included): the mean and range over seeds.
"""
from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np


def true_labels(frames: np.ndarray, schedule: str) -> np.ndarray:
    """The schedule's label at each frame index (``walk,run@120``: walk before 120, run from 120)."""
    starts, labels = [], []
    for i, part in enumerate(schedule.split(",")):
        label, _, at = part.partition("@")
        starts.append(int(at) if i else 0)
        labels.append(label)
    return np.array(labels)[np.searchsorted(np.array(starts), frames, side="right") - 1]


def scored_frames(frames: np.ndarray, schedule: str, skip: int, fade: int) -> np.ndarray:
    """Mask of the frames that count: not within ``skip`` of the first tracked frame or of a switch, nor in the
    ``fade`` frames before a switch."""
    keep = frames >= frames[0] + skip
    for part in schedule.split(",")[1:]:
        switch = int(part.partition("@")[2])
        keep &= ~((frames >= switch - fade) & (frames < switch + skip))
    return keep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--sequence", default="subject 16 walk then run")
    ap.add_argument("--schedule", default="walk,run@120")
    ap.add_argument("--skip", type=int, default=10)
    ap.add_argument("--fade", type=int, default=12)
    args = ap.parse_args()
    matches: dict[str, list[float]] = defaultdict(list)
    for path in sorted(args.results.glob("runs/*/result.json")):
        result = json.loads(path.read_text())
        summary = result.get("prior_summary")
        if result["run"]["sequence"] != args.sequence or not summary or "most_probable" not in summary:
            continue  # no posterior over labels (none, or a quantity such as the paced CRBM's pace)
        frames = np.arange(summary["first_frame"], summary["first_frame"] + len(summary["most_probable"]))
        keep = scored_frames(frames, args.schedule, args.skip, args.fade)
        guess = np.array(summary["most_probable"])[keep]
        matches[result["run"]["row"]].append(float(np.mean(guess == true_labels(frames, args.schedule)[keep])))
    print(f"| {args.sequence}: prior | most probable label = true activity (mean over seeds) | range | seeds |")
    print("|---|---|---|---|")
    for row, values in sorted(matches.items()):
        print(f"| {row} | {100 * np.mean(values):.0f}% | {100 * min(values):.0f}-{100 * max(values):.0f}% | "
              f"{len(values)} |")


if __name__ == "__main__":
    main()
