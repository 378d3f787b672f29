"""Tracking error on the held-out walk (run by hand: python benchmarks/heldout_tracking.py).

CMU 07_11 (used for nothing else: priors are trained or scaled on 07_01/07_02) is rendered once into
4 views (seed 0, default noise) and tracked from its first two frames over its whole length with
1000 particles, 4 views and 1 view (camera 0), 5 seeds each. Prints mean +- std (ddof 1) over the
seeds of the per-run mean marker errors (mm), and writes benchmarks/results/heldout_tracking.json.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.retarget import retarget  # noqa: E402
from data_tools.sequences.sequence import read_sequence  # noqa: E402
from data_tools.synthesis.synth import SynthConfig, synthesize  # noqa: E402
from priors.parts import HeightOffset
from priors.crbm.model import CRBMConfig  # noqa: E402
from priors.crbm.prior import CRBMPrior
from priors.crbm.training import train_crbm
from priors.gpdm.model import GPDMConfig  # noqa: E402
from priors.gpdm.prior import GPDMPrior
from priors.gpdm.training import train_gpdm_prior
from priors.random_walk import ConstantVelocityPrior, ZeroVelocityPrior  # noqa: E402
from tracker.core.representation import step_rms  # noqa: E402
from tracker.core.body import DOF_NAMES  # noqa: E402
from tracker import track  # noqa: E402
from tracker.core.metrics import summarize_runs  # noqa: E402

SHARED = REPO.parent / "shared"
MOCAP = SHARED / "mocap" / "cmu" / "07"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument("--priors", nargs="+",
                    default=["zero-velocity", "constant-velocity", "crbm-1", "crbm-3", "gpdm"],
                    help="zero-velocity, constant-velocity, crbm-1 (first order), crbm-3 (third order grown "
                         "from first order), gpdm (3D, linear+RBF, first order)")
    ap.add_argument("--bidirectional", action="store_true", help="also run 1 view with the bidirectional term")
    ap.add_argument("--out", default="heldout_tracking.json")
    args = ap.parse_args()
    asf = MOCAP / "07.asf"
    std = step_rms([retarget(asf_amc_clip(asf, MOCAP / f"07_{i}.amc"), fps=60).poses for i in ("01", "02")])
    priors = {}
    if "zero-velocity" in args.priors:
        priors["zero-velocity"] = ZeroVelocityPrior(std)
    if "constant-velocity" in args.priors:
        priors["constant-velocity"] = ConstantVelocityPrior(std)
    if any(p.startswith("crbm") for p in args.priors):
        # CRBMs trained on the four training walks (07_11 stays held out).
        train = [retarget(asf_amc_clip(asf, MOCAP / f"07_{i}.amc"), fps=60).poses for i in ("01", "02", "09", "10")]
        crbm = {o: train_crbm(train, CRBMConfig(order=o, hidden=150, epochs=500, cd_k=10), 60.0, DOF_NAMES,
                                rng=np.random.default_rng(o))
                for o in (1, 3)}
        for o in (1, 3):
            print(f"CRBM order {o}: trained in {crbm[o].training_seconds:.1f} s, reconstruction error "
                  f"{crbm[o].reconstruction_errors[-1]:.4f}", flush=True)
        if "crbm-1" in args.priors:
            priors["crbm-1"] = CRBMPrior([crbm[1]])
        if "crbm-3" in args.priors:
            priors["crbm-3"] = CRBMPrior([crbm[1], crbm[3]])
    if "gpdm" in args.priors:
        train = [retarget(asf_amc_clip(asf, MOCAP / f"07_{i}.amc"), fps=60).poses for i in ("01", "02", "09", "10")]
        gpdm = train_gpdm_prior(train, GPDMConfig(latent_dim=3, dynamics="linear+rbf", iterations=300), 60.0,
                                DOF_NAMES)
        print(f"GPDM: trained in {gpdm.gpdm.training_seconds:.1f} s on {sum(len(t) for t in train)} frames",
              flush=True)
        priors["gpdm"] = GPDMPrior(gpdm, height=HeightOffset(0.0))  # as its published rows ran
    configs = [("4 views", [0, 1, 2, 3], False), ("1 view", [0], False)]
    if args.bidirectional:
        configs.append(("1 view, bidirectional", [0], True))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        walk = retarget(asf_amc_clip(asf, MOCAP / "07_11.amc"), fps=60)
        synthesize(walk, Path(tmp) / "07_11", SynthConfig(frames=args.frames))
        seq = read_sequence(Path(tmp) / "07_11")
        for prior_name, prior in priors.items():
            for label, views, bidir in configs:
                means, secs = [], []
                for seed in range(args.seeds):
                    t0 = time.perf_counter()
                    run = track(seq, prior, particles=args.particles, seed=seed, views=views,
                                bidirectional=bidir,
                                annealing_layers=1)  # plain SIR, as the held-out tables were made
                    means.append(run.mean_error)
                    secs.append(run.seconds_per_frame)
                    print(f"  {prior_name}, {label}, seed {seed}: {run.mean_error:.1f} mm "
                          f"({time.perf_counter() - t0:.0f} s)", flush=True)
                m, s = summarize_runs(np.array(means))
                rows.append({"prior": prior_name, "views": label, "mean_mm": m, "std_mm": s,
                             "runs_mm": [round(x, 2) for x in means], "seconds_per_frame": float(np.mean(secs)),
                             "frames": int(len(run.errors))})
                print(f"{prior_name:18s} {label:24s} {m:6.1f} ± {s:5.1f} mm  ({np.mean(secs):.3f} s/frame)",
                      flush=True)
    out = REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / args.out).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
