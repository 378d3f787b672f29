"""Quick start: render a walk, train a CRBM on another, track with two priors and compare them.

    python examples/quickstart.py [--out quickstart_output] [--frames 60] [--particles 500] [--seeds 2]

Everything here is the public API (``import tracker``); the command line calls the same functions.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import tracker
from data_tools.samples import sample_walks  # the shipped CMU walks 07_01 and 07_02

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default="quickstart_output")
parser.add_argument("--frames", type=int, default=60)
parser.add_argument("--particles", type=int, default=500)
parser.add_argument("--seeds", type=int, default=2)
parser.add_argument("--epochs", type=int, default=300)
args = parser.parse_args()
out = Path(args.out)

# 1. Data: render one shipped walk into four cameras; the other walk trains the learned prior.
skeleton, (train_walk, test_walk) = sample_walks()
sequence = tracker.synthesize(test_walk, out / "sequence", skeleton=skeleton, frames=args.frames, seed=0,
                              overwrite=True)

# 2. A first-order CRBM trained on the other walk (the generator comes from the seed we pass).
crbm = tracker.train("crbm", [train_walk], skeletons=[skeleton], order=1, epochs=args.epochs, seed=0)
crbm.save(out / "crbm1.pt", overwrite=True)  # the script's own folder: a second run replaces its files

# 3. Track with each prior over a few seeds; each result can be saved as the command line does.
errors = {}
for prior, models in [("zero-velocity", []), ("crbm", [out / "crbm1.pt"])]:
    runs = [tracker.track(sequence, prior, models=models, particles=args.particles, seed=seed,
                          train_mocap=[train_walk])
            for seed in range(args.seeds)]
    runs[0].save(out / prior, overwrite=True)  # result.json + estimates.npz
    errors[prior] = tracker.summarize_runs([r.mean_error for r in runs])

# 4. Compare: mean ± std over seeds of the per-run mean absolute MPJPE (mm; the HumanEva marker error,
#    result.json's metrics["mpjpe_abs"]).
for prior, (mean, std) in errors.items():
    print(f"{prior:>14}: {mean:6.1f} ± {std:4.1f} mm over {args.seeds} seed(s)")
