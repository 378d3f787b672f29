"""Tracking speed on an idle machine and on one where another process keeps a core busy (run by hand).

    python benchmarks/threads_under_load.py [--frames 30] [--particles 1000]

Renders 32 frames of the shipped walk 07_02 into 4 views, trains a small first-order CRBM on 07_01, then
tracks with the CRBM prior in a fresh process for each case: idle and loaded (a busy-loop process pinned to
nothing, competing for one of the cores), each with ``--threads`` at its default (the available cores) and
with torch's and OpenCV's own defaults (``--threads`` not applied: the behaviour before threads were set
deliberately). Prints seconds per frame and the loaded / idle ratio.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

TRACK = """
import sys, time, tracker
if sys.argv[3] == "set":
    tracker.set_threads(None)
run = tracker.track(sys.argv[1], "crbm", models=[sys.argv[2]], particles=int(sys.argv[4]), frames=int(sys.argv[5]),
                    seed=0, annealing_layers=1)  # plain SIR, as the figures in docs/reference/performance.md were measured
print(run.seconds_per_frame)
"""


def busy() -> None:
    while True:
        pass


def seconds_per_frame(seq: Path, model: Path, threads: str, particles: int, frames: int) -> float:
    out = subprocess.run([sys.executable, "-c", TRACK, str(seq), str(model), threads, str(particles), str(frames)],
                         check=True, capture_output=True, text=True, cwd=REPO).stdout
    return float(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--particles", type=int, default=1000)
    args = parser.parse_args()
    import tracker
    from data_tools.samples import sample_walks

    asf, (train_walk, test_walk) = sample_walks()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        tracker.synthesize(test_walk, d / "seq", skeleton=asf, frames=args.frames + 2)
        tracker.train("crbm", [train_walk], skeletons=[asf], order=1, epochs=300, seed=0).save(d / "c1.pt")
        for threads in ("set", "library defaults"):
            idle = seconds_per_frame(d / "seq", d / "c1.pt", threads, args.particles, args.frames + 2)
            hog = mp.Process(target=busy, daemon=True)
            hog.start()
            time.sleep(0.5)
            try:
                loaded = seconds_per_frame(d / "seq", d / "c1.pt", threads, args.particles, args.frames + 2)
            finally:
                hog.terminate()
            print(f"threads {threads:>16}: idle {idle:.3f} s/frame, one core busy {loaded:.3f} s/frame, "
                  f"ratio {loaded / idle:.2f}")


if __name__ == "__main__":
    main()
