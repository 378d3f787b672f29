"""Where a frame's time goes (run by hand: python benchmarks/profile_hot_path.py [--threads 1] [--top 25]).

Two fixed workloads, each profiled with cProfile (the table sorted by cumulative time, then by own time):

1. the real PARSEC bodytrack frame (../shared/bodytrack/sequenceB_1, 10-cone model, provided masks), 1000
   particles x 5 annealing layers, zero-velocity prior, via ``tracker.track`` (reading + edge maps + filter);
2. a synthetic 4-view 15-cone sequence (CMU 07_11 rendered, 20 frames, background subtraction), 1000
   particles, zero-velocity prior.

Then the likelihood's stages, timed one by one on the synthetic frame (median of 20 calls, milliseconds per
1000 particles x 4 views, one thread): reading, observations, kinematics, the compiled cones-to-costs loop,
whole call.

The likelihood is the package's default, with the bidirectional term since 0.25.0; figures published for
earlier versions in docs/reference/performance.md are of the one-directional likelihood.
"""
from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO.parent / "shared"

from timing import median_ms  # noqa: E402


def profile(label: str, fn, top: int) -> None:
    fn()  # warm up imports and caches
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    prof.enable()
    fn()
    prof.disable()
    print(f"\n=== {label}: {time.perf_counter() - t0:.2f} s under the profiler ===")
    for key in ("cumulative", "tottime"):
        out = io.StringIO()
        stats = pstats.Stats(prof, stream=out).strip_dirs().sort_stats(key)
        stats.print_stats(top)
        lines = out.getvalue().splitlines()
        start = next(i for i, line in enumerate(lines) if line.lstrip().startswith("ncalls"))
        print(f"-- sorted by {key}")
        print("\n".join(lines[start:]).rstrip())


def stage_times(seq, P: int = 1000, repeats: int = 20) -> None:
    """Median milliseconds of each likelihood stage for ``P`` poses near frame 10's ground truth."""
    from likelihoods.compiled_costs import cone_costs
    from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood
    from tracker.core.kinematics import forward_kinematics

    V = seq.n_views
    lik = EdgeSilhouetteLikelihood(seq.model, seq.rig)
    frame = seq.frame(10, range(V))
    scorer = lik.prepare(frame)
    rng = np.random.default_rng(0)
    poses = seq.groundtruth.poses[10] + rng.normal(0, 0.02, (P, seq.model.n_dofs))
    kinematics = forward_kinematics(seq.model, poses)
    maps, edge, sil = scorer.maps, np.empty((P, V)), np.empty((P, V))
    stages = {
        "observations (read and decode 4 views)": lambda: seq.frame(10, range(V)),
        "observations (silhouettes, edge maps, cost maps)": lambda: lik.prepare(frame),
        "kinematics (forward_kinematics)": lambda: forward_kinematics(seq.model, poses),
        "cones to costs (compiled_costs.cone_costs)": lambda: cone_costs(
            kinematics, lik._tables(), maps.edge, maps.silhouette, maps.view_offset, maps.height, maps.width,
            lik.n_contour, edge, sil),
        "whole likelihood": lambda: scorer(poses),
    }
    print(f"\n=== likelihood stages, {P} particles x {V} views, one thread (median of {repeats}, ms) ===")
    for name, fn in stages.items():
        med, lo, hi = median_ms(fn, repeats)
        print(f"{name:55s} {med:8.2f}  (min {lo:.2f}, max {hi:.2f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--top", type=int, default=40)
    parser.add_argument("--synthetic", type=Path, default=None,
                        help="an existing synthetic sequence folder (default: render one)")
    args = parser.parse_args()
    import tracker

    tracker.set_threads(args.threads)
    bt = SHARED / "bodytrack" / "sequenceB_1"
    if bt.exists():
        seq = tracker.load_sequence(bt)
        profile("bodytrack frame, 1000 particles x 5 layers",
                lambda: tracker.track(seq, "zero-velocity", particles=1000, annealing_layers=5, seed=0), args.top)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.synthetic
        if folder is None:
            from data_tools.synthesis.synth import SynthConfig, synthesize

            folder = Path(tmp) / "walk"
            synthesize(tracker.load_clip(SHARED / "mocap" / "cmu" / "07" / "07_11.amc"), folder,
                       SynthConfig(frames=20))
        seq = tracker.load_sequence(folder)
        std = tracker.random_walk_scale(seq)  # (not part of a frame's work)
        profile(f"synthetic 15-cone, 1000 particles x 4 views, {seq.n_frames - 2} frames",
                lambda: tracker.track(seq, "zero-velocity", particles=1000, seed=0, step_std=std,
                                      annealing_layers=1), args.top)
        stage_times(seq)


if __name__ == "__main__":
    main()
