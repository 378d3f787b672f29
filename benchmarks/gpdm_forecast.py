"""GPDM forecasting (analogue of Wang 2005, Sec. 4.4) and a picture of the learned latent space (Fig. 4.1/4.6).

Run by hand: python benchmarks/gpdm_forecast.py. A 3D GPDM (first-order dynamics, balance M = 1) is trained
on the first 130 frames (about two gait cycles) of the 60 Hz walk 07_01 in the invariant representation
(normalised features). From each remaining test frame with 8 frames of future, the current pose is
projected into the latent space, its latent trajectory is predicted 8 frames ahead by mean prediction, and
also refined by trajectory optimisation (Sec. 4.3); the predicted pose (observation GP mean) is compared with
the true pose 8 frames later. Reported: RMS error over the normalised features, and over the joint angles in
degrees, for linear, RBF and linear+RBF dynamics. Writes benchmarks/results/gpdm_forecast.json and
gpdm_latent.png (training trajectory and mean-prediction simulations from three training points).
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from data_tools.motion.asf_amc import asf_amc_clip  # noqa: E402
from data_tools.motion.retarget import retarget  # noqa: E402
from priors.gpdm.predict import prepare  # noqa: E402
from priors.gpdm.model import GPDMConfig  # noqa: E402
from priors.gpdm.training import train_gpdm
from tracker.core.body import DOF_NAMES  # noqa: E402
from tracker.core.representation import FeatureNormaliser, feature_names, poses_to_invariant  # noqa: E402

MOCAP = REPO.parent / "shared" / "mocap" / "cmu" / "07"
TRAIN, AHEAD = 130, 8


def main() -> None:
    poses = retarget(asf_amc_clip(MOCAP / "07.asf", MOCAP / "07_01.amc"), fps=60).poses
    feats = poses_to_invariant(poses)[:-1]
    norm = FeatureNormaliser.fit(feats[:TRAIN], feature_names(DOF_NAMES))
    Y = norm.transform(feats)
    joints = [i for i, n in enumerate(norm.kept_names) if n not in
              ("forward_velocity", "lateral_velocity", "height", "pitch", "roll", "yaw_rate")]
    starts = np.arange(TRAIN, len(Y) - AHEAD)
    rows, models = {}, {}
    for dyn in ("linear", "rbf", "linear+rbf"):
        t0 = time.perf_counter()
        m = train_gpdm(Y[:TRAIN], [TRAIN], GPDMConfig(dynamics=dyn, iterations=300))
        secs = time.perf_counter() - t0
        p = prepare(m)
        models[dyn] = p
        cur = p.project(torch.tensor(Y[starts]))
        truth = torch.tensor(Y[starts + AHEAD])
        preds = {"mean prediction": [], "optimisation": []}
        for i in range(len(starts)):
            mean_traj = p.simulate(cur[i:i + 1], AHEAD)
            opt_traj = p.optimize_trajectory(cur[i:i + 1], mean_traj)
            preds["mean prediction"].append(p.predict_pose(mean_traj[-1:])[0][0])
            preds["optimisation"].append(p.predict_pose(opt_traj[-1:])[0][0])
        for how, ys in preds.items():
            err = torch.stack(ys) - truth
            rms = float(err.pow(2).mean().sqrt())
            deg = float((err[:, joints] * torch.tensor(norm.std[norm.keep][joints])).pow(2).mean().sqrt()) \
                * 180 / np.pi
            rows.setdefault(how, {})[dyn] = {"rms_normalised": rms, "rms_joint_degrees": deg}
        print(f"{dyn}: trained in {secs:.1f} s", flush=True)
    print(f"8-frame-ahead forecasting on 07_01 frames {TRAIN}..{len(Y) - 1} ({len(starts)} starts); "
          "RMS over normalised features / joint angles (degrees)")
    print(f"{'':18s}" + "".join(f"{d:>22s}" for d in ("linear", "rbf", "linear+rbf")))
    for how, r in rows.items():
        print(f"{how:18s}" + "".join(f"{r[d]['rms_normalised']:12.3f} /{r[d]['rms_joint_degrees']:6.2f} deg"
                                      for d in ("linear", "rbf", "linear+rbf")))
    out = REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "gpdm_forecast.json").write_text(json.dumps(rows, indent=1))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    p = models["linear+rbf"]
    X = p.X.numpy()
    fig = plt.figure(figsize=(7, 6), dpi=120)
    ax = fig.add_subplot(projection="3d")
    ax.plot(X[:, 0], X[:, 1], X[:, 2], "b.-", markersize=3, linewidth=0.8, label="training latent trajectory")
    for k, s in enumerate((0, 40, 80)):
        sim = p.simulate(p.X[s:s + 1], 300).numpy()
        ax.plot(sim[:, 0], sim[:, 1], sim[:, 2], "r-", linewidth=1.2, label="mean prediction" if k == 0 else None)
    ax.set_title("GPDM latent space (07_01, linear+RBF dynamics)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "gpdm_latent.png")


if __name__ == "__main__":
    main()
