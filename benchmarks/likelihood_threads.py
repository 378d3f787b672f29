"""How the likelihood scales with threads (run by hand: python benchmarks/likelihood_threads.py [--rounds 5]).

Scores batches of poses near the truth with the CPU path of the edge + silhouette likelihood on one and on two
threads, rounds interleaved, at 1000 and 4000 particles, on two frames: PARSEC bodytrack's real four-camera
frame (../shared/bodytrack/sequenceB_1, its 10-cone model and provided masks) and a synthetic four-view frame of
the 15-cone model (CMU 07_11 rendered). Prints the median milliseconds of a call (the frame's cost maps made
once) and the speed-up of two threads over one.

The likelihood is the package's default, with the bidirectional term since 0.25.0; figures published for
earlier versions in docs/reference/performance.md are of the one-directional likelihood.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO.parent / "shared"


def frames(tmp: Path):
    """(label, model, rig, frame, pose near which to score) of each frame measured."""
    import tracker

    bodytrack = SHARED / "bodytrack" / "sequenceB_1"
    if bodytrack.exists():
        seq = tracker.load_sequence(bodytrack)
        yield "bodytrack frame (10 cones, 4 cameras)", seq, seq.frame(0, range(seq.n_views)), \
            np.asarray(seq.initial_poses)[-1]
    from data_tools.synthesis.synth import SynthConfig, synthesize

    synthesize(tracker.load_clip(SHARED / "mocap" / "cmu" / "07" / "07_11.amc"), tmp / "walk", SynthConfig(frames=12))
    seq = tracker.load_sequence(tmp / "walk")
    yield "synthetic 07_11 (15 cones, 4 views)", seq, seq.frame(10, range(seq.n_views)), seq.groundtruth.poses[10]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds of --calls calls each")
    parser.add_argument("--calls", type=int, default=10)
    parser.add_argument("--particles", type=int, nargs="+", default=[1000, 4000])
    args = parser.parse_args()
    import tracker
    from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood

    tracker.set_threads(2)
    with tempfile.TemporaryDirectory() as tmp:
        for label, seq, frame, pose in frames(Path(tmp)):
            scorers = {n: EdgeSilhouetteLikelihood(seq.model, seq.rig, threads=n).prepare(frame) for n in (1, 2)}
            rng = np.random.default_rng(0)
            for P in args.particles:
                poses = pose + rng.normal(0.0, 0.05, (P, pose.size))
                times = {n: [] for n in scorers}
                for scorer in scorers.values():
                    scorer(poses)  # compile and warm the caches
                for _ in range(args.rounds):
                    for n, scorer in scorers.items():
                        for _ in range(args.calls):
                            t0 = time.perf_counter()
                            scorer(poses)
                            times[n].append(time.perf_counter() - t0)
                one, two = (1000 * float(np.median(times[n])) for n in (1, 2))
                print(f"{label}, {P} particles: 1 thread {one:.2f} ms, 2 threads {two:.2f} ms, "
                      f"speed-up {one / two:.2f}", flush=True)


if __name__ == "__main__":
    main()
