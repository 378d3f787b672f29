"""Time one frame of FCRBM sampling for 1000 particles (the prior's whole ``sample``: invariant features,
normalisation, style switching, Gibbs sampling, integration of the root), against the CRBM prior of the same size.

    python benchmarks/fcrbm_sampling.py [--particles 1000] [--threads 1] [--frames 30]

Models have the default sizes (order 3, 150 hidden units; the FCRBM 100 factors, 20 style features, labels walk,
run, punch) and are trained for 2 epochs only: the cost of sampling does not depend on the weights' values.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "mocap" / "cmu"


def time_prior(prior, history: np.ndarray, known: np.ndarray, particles: int, frames: int) -> np.ndarray:
    """Seconds per ``sample`` call over ``frames`` calls (after two warm-up calls)."""
    rng = np.random.default_rng(0)
    state = prior.start(known, particles, rng)
    for _ in range(2):
        prior.sample(history, prior.order, state, rng)
    seconds = []
    for _ in range(frames):
        t0 = time.perf_counter()
        _, state = prior.sample(history, prior.order, state, rng)
        seconds.append(time.perf_counter() - t0)
    return np.array(seconds)


def main() -> None:
    from data_tools.motion.load import load_training_clips
    from priors.crbm.model import CRBMConfig
    from priors.crbm.prior import CRBMPrior
    from priors.crbm.training import train_crbm
    from priors.fcrbm.training import train_fcrbm
    from priors.settings import FCRBMConfig
    from priors.fcrbm.prior import FCRBMPrior
    from tracker.core.body import DOF_NAMES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    clips = [c.poses for c in load_training_clips([MOCAP / "02" / f for f in ("02_01.amc", "02_03.amc", "02_05.amc")],
                                                  None, 60.0)]
    rng = np.random.default_rng(0)
    fcrbm = train_fcrbm(clips, ["walk", "run", "punch"], FCRBMConfig(epochs=2), 60.0, DOF_NAMES, rng=rng)
    crbm = train_crbm(clips, CRBMConfig(epochs=2), 60.0, DOF_NAMES, rng=rng)
    known = clips[0][:4]
    history = np.repeat(known[None, 1:], args.particles, axis=0)
    print(f"{args.particles} particles, {args.threads} thread(s), median (min) of {args.frames} frames:")
    for steps in (30, 20, 10):
        for name, prior in [("fcrbm", FCRBMPrior([fcrbm], gibbs_steps=steps)),
                            ("crbm", CRBMPrior([crbm], gibbs_steps=steps))]:
            s = time_prior(prior, history, known, args.particles, args.frames) * 1000
            print(f"  {name:5s} {steps:2d} Gibbs steps: {np.median(s):6.1f} ms ({s.min():.1f} ms)")


if __name__ == "__main__":
    main()
