"""Our tracker beside PARSEC's C++ bodytrack on its own real frame (run by hand).

    python benchmarks/bodytrack_side_by_side.py [--rounds 3] [--settings 4000x5 1000x5] [--threads 2]

Builds bodytrack from ../shared/bodytrack/parsec (its build.sh; binaries cached in ../parsec-bin beside
shared/), then, in interleaved rounds on ../shared/bodytrack/sequenceB_1, times:

* ours: ``tracker.track`` with the zero-velocity prior and annealing (PARSEC's PoseParameters.txt scale) and
  the likelihood bodytrack computes, edges and the one-directional silhouette cost (``bidirectional=False``;
  the package's default adds the uncovered foreground, work bodytrack does not do), per-frame time = reading the frame's images and masks + edge maps + the annealed filter step (the
  ``seconds_per_frame`` of the result: load + observe + filter);
* bodytrack serial and with 2 pthreads: PARSEC's own frame-loop timer (image loading, edge maps, the
  annealed likelihood evaluations, the estimate).

Prints per-setting medians and the ratios bodytrack / ours (above 1: we are faster).
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO.parent / "shared"
PARSEC = SHARED / "bodytrack" / "parsec"
SEQUENCE = SHARED / "bodytrack" / "sequenceB_1"
BIN = REPO.parent / "parsec-bin"


def build() -> None:
    if (BIN / "bodytrack-serial").exists() and (BIN / "bodytrack-pthreads").exists():
        return
    print("building PARSEC bodytrack ...", flush=True)
    subprocess.run(["bash", str(PARSEC / "build.sh")], check=True, env={**os.environ, "BIN": str(BIN)},
                   stdout=subprocess.DEVNULL)


def parsec_seconds(binary: str, work: Path, particles: int, layers: int, threads: int) -> float:
    model = "4" if binary == "bodytrack-serial" else "2"
    out = subprocess.run([str(BIN / binary), str(work), "4", "1", str(particles), str(layers), model,
                          str(threads), "0"], check=True, capture_output=True, text=True).stdout
    return float(re.search(r"ROI: ([0-9.]+)s", out).group(1))


def ours_seconds(seq, particles: int, layers: int, seed: int) -> float:
    import tracker

    run = tracker.track(seq, "zero-velocity", particles=particles, annealing_layers=layers, seed=seed,
                        bidirectional=False)
    return run.seconds_per_frame


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--settings", nargs="+", default=["4000x5", "1000x5"])
    parser.add_argument("--threads", type=int, default=2, help="threads for our tracker (default 2)")
    args = parser.parse_args()
    if not SEQUENCE.exists():
        sys.exit(f"bodytrack frame not found at {SEQUENCE}")
    build()
    import tracker

    tracker.set_threads(args.threads)
    seq = tracker.load_sequence(SEQUENCE)
    ours_seconds(seq, 200, 2, 0)  # warm up imports and caches
    work = Path(tempfile.mkdtemp())
    try:
        for name in ("s", "p"):
            shutil.copytree(SEQUENCE, work / name)
        for setting in args.settings:
            P, L = (int(x) for x in setting.split("x"))
            times: dict[str, list[float]] = {"ours": [], "serial": [], "pthreads2": []}
            for r in range(args.rounds):
                times["ours"].append(ours_seconds(seq, P, L, r))
                times["serial"].append(parsec_seconds("bodytrack-serial", work / "s", P, L, 1))
                times["pthreads2"].append(parsec_seconds("bodytrack-pthreads", work / "p", P, L, 2))
            med = {k: float(np.median(v)) for k, v in times.items()}
            print(f"{P} particles x {L} layers, {args.rounds} interleaved rounds (per-frame medians): "
                  f"ours {med['ours']:.3f} s ({args.threads} threads), bodytrack serial {med['serial']:.3f} s, "
                  f"bodytrack pthreads x2 {med['pthreads2']:.3f} s; ratio bodytrack x2 / ours "
                  f"{med['pthreads2'] / med['ours']:.2f}, serial / ours {med['serial'] / med['ours']:.2f}")
            for k, v in times.items():
                print(f"  {k}: " + ", ".join(f"{x:.3f}" for x in v))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
