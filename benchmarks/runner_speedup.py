"""The experiment runner's parallel speed-up and overhead (run by hand on an otherwise idle machine).

    python benchmarks/runner_speedup.py

Runs benchmarks/experiments/speedup_12_runs.toml from scratch with --jobs 1 and with --jobs 2 (sequences
rendered once beforehand and shared, so both time only the runs), and prints the wall times, their ratio, and
the runner's overhead per run (wall time x jobs minus the runs' own time, over the runs).
"""
from __future__ import annotations

import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
EXPERIMENT = REPO / "benchmarks" / "experiments" / "speedup_12_runs.toml"


def main() -> None:
    from tracker.app.compare import compare

    work = Path(tempfile.mkdtemp())
    try:
        compare(EXPERIMENT, work / "warm", jobs=1, say=lambda s: None, progress=False)  # renders the sequence
        walls = {}
        for jobs in (1, 2):
            out = work / f"jobs{jobs}"
            shutil.copytree(work / "warm" / "sequences", out / "sequences")
            t0 = time.perf_counter()
            compare(EXPERIMENT, out, jobs=jobs, say=lambda s: None, progress=False)
            walls[jobs] = time.perf_counter() - t0
            meta = json.loads((out / "experiment.json").read_text())
            overhead = (meta["wall_seconds_now"] * jobs - meta["run_seconds_now"]) / meta["ran_now"]
            print(f"--jobs {jobs}: {walls[jobs]:.1f} s in all, {meta['wall_seconds_now']:.1f} s running "
                  f"{meta['ran_now']} runs ({meta['run_seconds_now']:.1f} s of run time, "
                  f"{meta['threads_per_worker']} thread(s) per worker); runner overhead {overhead:.2f} s per run")
        print(f"--jobs 2 / --jobs 1 = {walls[2] / walls[1]:.2f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
