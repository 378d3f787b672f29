"""Tracking speed (run by hand: python benchmarks/tracking_benchmark.py).

1. Synthetic 15-cone sequence (CMU 07_11 rendered into 4 views), 1000 particles, zero-velocity prior (1 and 2:
   one layer, plain SIR, as the figures in docs/reference/performance.md were measured; track's default is 3 layers):
   frames per second of the whole loop (observations + prior + likelihood + resampling) and likelihood
   evaluations per second (particle-views per second), with a per-stage breakdown.
2. The same sequence tracked with a CRBM-3 prior, 1000 particles x 4 views: frames per second at 30 Gibbs steps
   and at the default, with one layer and with track's default annealing (the speed target: 20), and the
   CRBM's sampling time alone at orders 1, 3, 6.

PARSEC bodytrack's own frame, beside the C++ program, is benchmarks/bodytrack_side_by_side.py.

The likelihood is the package's default, with the bidirectional term since 0.25.0; figures published for
earlier versions in docs/reference/performance.md are of the one-directional likelihood.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from timing import best_ms  # noqa: E402

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.retarget import retarget  # noqa: E402
from data_tools.sequences.sequence import read_sequence  # noqa: E402
from data_tools.synthesis.synth import SynthConfig, synthesize  # noqa: E402
from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood  # noqa: E402
from priors.random_walk import ZeroVelocityPrior  # noqa: E402
from tracker import track  # noqa: E402
from tracker.core.representation import step_rms  # noqa: E402

SHARED = REPO.parent / "shared"


def synthetic(tmp: Path) -> None:
    mocap = SHARED / "mocap" / "cmu" / "07"
    asf = mocap / "07.asf"
    walk = retarget(asf_amc_clip(asf, mocap / "07_11.amc"), fps=60)
    synthesize(walk, tmp / "walk", SynthConfig(frames=42))
    seq = read_sequence(tmp / "walk")
    std = step_rms([retarget(asf_amc_clip(asf, mocap / f"07_{i}.amc"), fps=60).poses for i in ("01", "02")])
    P, V = 1000, 4
    run = track(seq, ZeroVelocityPrior(std), particles=P, seed=0, annealing_layers=1)  # plain SIR, as published
    r = run.records
    n = len(r["filter_seconds"])
    per_frame = run.seconds_per_frame
    observe = (r["load_seconds"] + r["observe_seconds"]).mean()
    print(f"15-cone, {P} particles x {V} views, {n} frames: {per_frame * 1000:.0f} ms per frame "
          f"= {1 / per_frame:.1f} frames/s (reading and observations {observe * 1000:.0f} ms, overlapped with the "
          f"filter, filter {r['filter_seconds'].mean() * 1000:.0f} ms); mean error {run.mean_error:.1f} mm")
    lik = EdgeSilhouetteLikelihood(seq.model, seq.rig)
    scorer = lik.prepare(seq.frame(20, range(V)))
    poses = seq.groundtruth.poses[20] + np.random.default_rng(0).normal(0, 1, (P, 40)) * std
    for threads in (1, 2):
        lik.threads = threads
        ms = best_ms(lambda: scorer(poses))
        print(f"  likelihood alone, {threads} thread(s): {ms:.1f} ms per {P} particles -> "
              f"{P * V / ms * 1000:,.0f} particle-views/s")
    lik.threads = 1
    prior = ZeroVelocityPrior(std)
    hist = np.repeat(poses[:, None], 1, axis=1)
    rng = np.random.default_rng(0)
    print(f"  prior sample: {best_ms(lambda: prior.sample(hist, 1, None, rng)):.2f} ms; "
          f"observations (4 views): {best_ms(lambda: lik.prepare(seq.frame(20, range(V)))):.1f} ms")


def crbm_tracking(tmp: Path) -> None:
    """The CRBM speed target: 15-cone model, 1000 particles x 4 views, synthetic 07_11, CRBM prior (order 3
    grown from 1, trained with train's defaults on 07_01, 07_02, 07_09, 07_10), frames per second of the whole
    loop (observations included), at 30 Gibbs steps (the default before 0.4.0) and at the default, with one
    layer (plain SIR, as published) and with track's default annealing layers."""
    from priors.crbm.prior import GIBBS_STEPS
    from tracker import train
    from tracker.app.schema import TRACK_ANNEALING_LAYERS

    mocap = SHARED / "mocap" / "cmu" / "07"
    model = train("crbm", [mocap / f"07_{i}.amc" for i in ("01", "02", "09", "10")], order=3)
    model.save(tmp / "crbm3.pt")
    seq = read_sequence(tmp / "walk")
    for steps, layers in ((30, 1), (GIBBS_STEPS, 1), (GIBBS_STEPS, TRACK_ANNEALING_LAYERS)):
        runs = [track(seq, "crbm", models=[tmp / "crbm3.pt"], particles=1000, seed=seed, annealing_layers=layers,
                      gibbs_steps=steps) for seed in range(3)]
        per_frame = np.median([r.seconds_per_frame for r in runs])
        wait = np.median([np.median(r.records["load_seconds"] + r.records["observe_seconds"]) for r in runs])
        filt = np.median([np.median(r.records["filter_seconds"]) for r in runs])
        print(f"CRBM-3 tracking, 1000 particles x 4 views x {layers} layer(s), {steps} Gibbs steps: "
              f"{per_frame * 1000:.0f} ms per frame "
              f"= {1 / per_frame:.1f} frames/s (median of 3 seeds; per frame, medians: reading and observations of "
              f"the next frame, overlapped with the filter, "
              f"{wait * 1000:.0f} ms, filter {filt * 1000:.0f} ms); mean errors "
              f"{', '.join(f'{r.mean_error:.1f}' for r in runs)} mm")


def crbm_sampling() -> None:
    """CRBM prior: time to sample the next pose of 1000 particles (the default Gibbs steps), orders 1, 3, 6."""
    from priors.crbm.model import CRBMConfig
    from priors.crbm.prior import CRBMPrior
    from priors.crbm.training import train_crbm
    from tracker.core.body import DOF_NAMES

    mocap = SHARED / "mocap" / "cmu" / "07"
    asf = mocap / "07.asf"
    train = [retarget(asf_amc_clip(asf, mocap / f"07_{i}.amc"), fps=60).poses for i in ("01", "02", "09", "10")]
    for order in (1, 3, 6):
        model = train_crbm(train, CRBMConfig(order=order, hidden=150, epochs=500), 60.0, DOF_NAMES,
                           rng=np.random.default_rng(0))
        prior = CRBMPrior([model])
        hist = np.repeat(train[0][None, 20:20 + order], 1000, axis=0)
        state = prior.start(train[0][:20 + order], 1000, np.random.default_rng(0))
        rng = np.random.default_rng(0)
        ms = best_ms(lambda: prior.sample(hist, order, state, rng))
        print(f"CRBM order {order} (150 hidden, trained 500 epochs on {sum(len(t) for t in train)} frames in "
              f"{model.training_seconds:.1f} s): {ms:.1f} ms to sample 1000 particles")


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as d:
        synthetic(Path(d))
        crbm_tracking(Path(d))
    crbm_sampling()
