"""M-step-ahead prediction on a held-out walk (analogue of Taylor 2009, Fig. 6.3).

Run by hand: python benchmarks/crbm_prediction.py. CRBMs of order 1, 3 and 6 (150 hidden units, CD-10,
500 epochs) are trained on the subject-7 training walks 07_01, 07_02, 07_09, 07_10 at 60 Hz. From every
frame t0 of the held-out walk 07_11 with 7 frames of history, each method predicts frames t0+1 .. t0+20
from the true past alone; the error is the mean marker distance (mm) between the body model at the
predicted and at the true pose, averaged over all t0. Methods: CRBM Gibbs sampling (30 steps, one sample
path), CRBM free-energy descent (eq. 4.19, L-BFGS), the last frame, and constant velocity. Writes
benchmarks/results/crbm_prediction.{json,png} and prints a table.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.retarget import retarget  # noqa: E402
from priors.parts import GroundDiffusion
from priors.crbm.model import CRBMConfig  # noqa: E402
from priors.crbm.prior import CRBMPrior
from priors.crbm.training import train_crbm
from tracker.core.body import DOF_NAMES  # noqa: E402
from tracker.core.kinematics import markers  # noqa: E402
from tracker.core.metrics import marker_error  # noqa: E402
from rollout_error import rollout  # noqa: E402  (the benchmarks folder is the script's own)

MOCAP = REPO.parent / "shared" / "mocap" / "cmu" / "07"
HORIZON = 20
HISTORY = 7


def main() -> None:
    asf = MOCAP / "07.asf"
    train = [retarget(asf_amc_clip(asf, MOCAP / f"07_{i}.amc"), fps=60).poses for i in ("01", "02", "09", "10")]
    test = retarget(asf_amc_clip(asf, MOCAP / "07_11.amc"), fps=60)
    model = test.model
    T = len(test.poses)
    starts = np.arange(HISTORY - 1, T - HORIZON)
    past = np.stack([test.poses[t - HISTORY + 1:t + 1] for t in starts])  # S x HISTORY x D
    future = np.stack([test.poses[t + 1:t + 1 + HORIZON] for t in starts])  # S x H x D
    truth = markers(model, future)
    results = {}
    last = np.repeat(past[:, -1:], HORIZON, axis=1)
    vel = past[:, -1] - past[:, -2]
    constvel = past[:, -1:] + vel[:, None] * np.arange(1, HORIZON + 1)[None, :, None]
    results["last frame"] = last
    results["constant velocity"] = constvel
    for order in (1, 3, 6):
        m = train_crbm(train, CRBMConfig(order=order, hidden=150, epochs=500, cd_k=10), 60.0, DOF_NAMES,
                       rng=np.random.default_rng(0))
        print(f"order {order}: trained in {m.training_seconds:.1f} s", flush=True)
        results[f"CRBM-{order} Gibbs"] = rollout(CRBMPrior([m], gibbs_steps=30, ground=GroundDiffusion(0.0)), past, HORIZON, seed=0)
        results[f"CRBM-{order} free energy"] = rollout(CRBMPrior([m], mode="free-energy", ground=GroundDiffusion(0.0)), past, HORIZON,
                                                       seed=0)
    table = {name: marker_error(markers(model, pred), truth).mean(axis=0) for name, pred in results.items()}
    steps = [1, 2, 3, 5, 10, 15, 20]
    print("M-step-ahead prediction error on 07_11 (mm, mean over", len(starts), "start frames)")
    print(f"{'method':26s}" + "".join(f"{'M=' + str(s):>8s}" for s in steps))
    for name, err in table.items():
        print(f"{name:26s}" + "".join(f"{err[s - 1]:8.1f}" for s in steps))
    out = REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "crbm_prediction.json").write_text(json.dumps({k: [float(x) for x in v] for k, v in table.items()},
                                                         indent=1))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4), dpi=120)
    for name, err in table.items():
        ax.plot(np.arange(1, HORIZON + 1), err, label=name, linestyle="--" if "free" in name else "-")
    ax.set_xlabel("frames ahead (M, 60 Hz)")
    ax.set_ylabel("marker error (mm)")
    ax.set_title("Prediction on the held-out walk 07_11")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "crbm_prediction.png")


if __name__ == "__main__":
    main()
