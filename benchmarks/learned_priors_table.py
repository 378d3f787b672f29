"""One table of the learned priors against zero-velocity over several `compare` folders, training seeds pooled.

    python benchmarks/learned_priors_table.py "4 views, 1000 particles=results/learned_priors_main" \\
        "250 particles=results/learned_priors_few" "hard=results/learned_priors_hard" [--baseline zero-velocity]

Each argument is ``CONDITION=FOLDER`` (a folder `compare` wrote); a folder whose experiment has several view sets
splits its condition by them (", 4 views", ", 1 view" are added to the condition), and a sequence named
``"NAME (...), VARIANT"`` (a rendering variant: an occluder, a dead camera) adds ``VARIANT`` to the condition.
Rows that repeat one prior with several training seeds (labels ending in ``", training seed S"``) are pooled: a
prior's error on a cell (a sequence in a condition) is the mean over its training seeds and tracking seeds of each
run's mean marker error (absolute MPJPE, mm). The paired difference to the baseline pairs every run with the
baseline's run of the same tracking seed (same generator seed, hence the same noise), one pair per training seed
and tracking seed, with a 95% percentile bootstrap interval over those pairs. Prints, per condition, each prior's
ratio to the baseline and its paired difference on every sequence, then a summary over all cells: the geometric
mean of the ratios, the worst ratio, the cells where the prior's interval lies below zero (better) or above it
(worse), and its seconds per frame over the baseline's (as the runs recorded them: compare them only between
runs made under the same load).
"""
from __future__ import annotations

import argparse
import json
import math
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

from tracker.app.report import PRIMARY, bootstrap_interval, per_run

SEED_SUFFIX = re.compile(r", training seed (\d+)$")


def view_name(views: list[int]) -> str:
    """``"4 views"`` or ``"1 view"``."""
    return f"{len(views)} view" + ("s" if len(views) != 1 else "")


def read_runs(condition: str, folder: Path, several_view_sets: bool) -> list[dict]:
    """Every finished run of ``folder`` as ``{cell, prior, training_seed, seed, error, spf}``."""
    runs = []
    for path in sorted((folder / "runs").glob("*/result.json")):
        r = json.loads(path.read_text())
        info = r["run"]
        label = info["row"].rpartition(", views ")[0] if ", views " in info["row"] else info["row"]
        m = SEED_SUFFIX.search(label)
        prior, training_seed = (label[:m.start()], int(m.group(1))) if m else (label, None)
        cond = f"{condition}, {view_name(info['views'])}" if several_view_sets else condition
        sequence, sep, variant = info["sequence"].partition("), ")  # "NAME (...), occluder ...": a condition
        sequence, cond = (sequence + ")", f"{cond}, {variant}") if sep else (info["sequence"], cond)
        runs.append({"cell": (cond, sequence), "prior": prior, "training_seed": training_seed,
                     "seed": info["seed_index"], "error": per_run(r, PRIMARY),
                     "spf": r.get("seconds_per_frame")})
    return runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", metavar="CONDITION=FOLDER")
    parser.add_argument("--baseline", default="zero-velocity")
    args = parser.parse_args()
    runs = []
    for arg in args.folders:
        condition, sep, folder = arg.rpartition("=")
        if not sep:
            raise SystemExit(f"{arg}: give CONDITION=FOLDER")
        folder = Path(folder)
        view_sets = {json.dumps(r["run"]["views"]) for r in (json.loads(p.read_text()) for p in
                                                              (folder / "runs").glob("*/result.json"))}
        runs += read_runs(condition, folder, len(view_sets) > 1)
    by = defaultdict(list)  # (cell, prior) -> runs
    for r in runs:
        by[(r["cell"], r["prior"])].append(r)
    cells = list(dict.fromkeys(r["cell"] for r in runs))
    priors = [p for p in dict.fromkeys(r["prior"] for r in runs) if p != args.baseline]
    summary = defaultdict(lambda: {"ratios": [], "better": 0, "worse": 0, "spf": []})
    for condition in dict.fromkeys(c for c, _ in cells):
        seqs = sorted(s for c, s in cells if c == condition)
        print(f"\n### {condition}: ratio to {args.baseline}; paired difference, mm [95% interval]\n")
        base_cells = [f"{np.mean([r['error'] for r in by[((condition, s), args.baseline)]]):.1f} mm"
                      for s in seqs]
        print("| prior | " + " | ".join(seqs) + " |\n|---|" + "---|" * len(seqs))
        print(f"| {args.baseline} | " + " | ".join(base_cells) + " |")
        for prior in priors:
            if not any((cell, prior) in by for cell in ((condition, s) for s in seqs)):
                continue  # a prior this condition did not track
            row = []
            for s in seqs:
                cell = (condition, s)
                mine, base = by.get((cell, prior), []), by.get((cell, args.baseline), [])
                base_by_seed = {r["seed"]: r for r in base}
                pairs = [(r, base_by_seed[r["seed"]]) for r in mine if r["seed"] in base_by_seed]
                if not pairs:
                    row.append("")
                    continue
                d = np.array([a["error"] - b["error"] for a, b in pairs])
                ratio = np.mean([a["error"] for a in mine]) / np.mean([b["error"] for b in base])
                lo, hi = bootstrap_interval(d)
                summary[prior]["ratios"].append(ratio)
                summary[prior]["better"] += hi < 0
                summary[prior]["worse"] += lo > 0
                spf = [a["spf"] / b["spf"] for a, b in pairs if a["spf"] and b["spf"]]
                summary[prior]["spf"] += spf
                row.append(f"{ratio:.2f} ({d.mean():+.1f} [{lo:+.1f}, {hi:+.1f}])")
            print(f"| {prior} | " + " | ".join(row) + " |")
    print(f"\n### Over all {len(cells)} cells\n")
    print(f"| prior | geometric mean ratio | worst ratio | better / worse than {args.baseline} (interval "
          "excludes 0) | cells | seconds per frame / baseline's |\n|---|---|---|---|---|---|")
    for prior in sorted(priors, key=lambda p: sum(map(math.log, summary[p]["ratios"])) / len(summary[p]["ratios"])):
        s = summary[prior]
        gm = math.exp(sum(map(math.log, s["ratios"])) / len(s["ratios"]))
        spf = f"{np.median(s['spf']):.2f}" if s["spf"] else ""
        print(f"| {prior} | {gm:.2f} | {max(s['ratios']):.2f} | {s['better']} / {s['worse']} | "
              f"{len(s['ratios'])} | {spf} |")


if __name__ == "__main__":
    main()
