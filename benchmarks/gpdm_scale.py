"""GPDM at scale: training time, prior step time and forecasting of a sparse GPDM on ~2000 frames of several
subjects, against the exact GPDM on a subset small enough for it.

Run by hand: OMP_NUM_THREADS=1 python benchmarks/gpdm_scale.py [--frames 2000] [--inducing 200]
[--exact-frames 500] [--iterations 300] [--methods dtc vfe fitc]

Training data: the 60 Hz walks of subjects 2 (02_01, 02_02), 7 (07_01, 07_02, 07_09, 07_10, 07_11) and 91
(91_straight_walk, then 91_slow_walk cut so that the total is ``--frames``). One feature normaliser, fitted on
all of them, serves every model, so normalised errors compare across models. Models (3D, linear+RBF, first
order, balance 1, ``--iterations`` L-BFGS iterations):

* ``sparse, all``: the sparse GPDM (``--inducing`` frames; DTC, and any other ``--methods``) on all frames;
* ``exact, subset``: the exact GPDM on a subset: the first ``--exact-frames / 3`` frames of the first walk of
  each subject (02_01, 07_01, 91_straight_walk; 2.5 gait cycles each);
* ``sparse, subset``: the sparse GPDM (DTC) on that same subset (the cost of the approximation alone).

Forecasting (as benchmarks/gpdm_forecast.py, after Wang 2005 Sec. 4.4) on the held-out walk of subject 16
(16_15, never trained on), and on the 300 frames of 91_slow_walk that follow the part trained on (a training
subject, unseen frames): from every frame with 8 frames of future, the pose is projected into the latent space,
its latent trajectory is mean-predicted 8 frames ahead, and the observation GP's mean pose is compared with
the true pose 8 frames later. Reported: RMS over the normalised features and over the joint angles (degrees),
and for scale the same for holding the current pose. Step time: ``GPDMPrior.sample`` for 1000 particles,
best of 20. Writes benchmarks/results/gpdm_scale.json.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from data_tools.motion.load import load_training_clips  # noqa: E402
from priors.gpdm.predict import prepare  # noqa: E402
from priors.parts import HeightOffset  # noqa: E402
from priors.gpdm.model import SPARSE_METHODS, GPDMConfig  # noqa: E402
from priors.gpdm.prior import GPDMPrior
from priors.gpdm.model import GPDMPriorModel
from priors.gpdm.training import train_gpdm
from tracker.core.body import DOF_NAMES  # noqa: E402
from tracker.core.representation import clip_features, poses_to_invariant, step_rms  # noqa: E402

MOCAP = REPO.parent / "shared" / "mocap" / "cmu"
TRAIN = ["02/02_01", "02/02_02", "07/07_01", "07/07_02", "07/07_09", "07/07_10", "07/07_11",
         "91/91_straight_walk", "91/91_slow_walk"]
TEST = "16/16_15"
AHEAD, PARTICLES = 8, 1000


def forecast(model, Y_test: np.ndarray, joints: list[int], joint_std: np.ndarray) -> dict:
    """8-frame-ahead mean-prediction errors from every start of the normalised test features."""
    p = prepare(model)
    starts = np.arange(len(Y_test) - AHEAD)
    x = p.project(torch.tensor(Y_test[starts]))
    with torch.no_grad():
        for _ in range(AHEAD):  # first-order dynamics: the input is the newest latent point
            x, _ = p.predict_latent(x)
        pred = p.predict_pose(x)[0].numpy()
    out = {}
    for name, guess in (("model", pred), ("hold current pose", Y_test[starts])):
        err = guess - Y_test[starts + AHEAD]
        out[name] = {"rms_normalised": float(np.sqrt((err ** 2).mean())),
                     "rms_joint_degrees": float(np.sqrt(((err[:, joints] * joint_std) ** 2).mean()) * 180 / np.pi)}
    return out


def step_ms(model, norm, clips) -> float:
    """Best of 20 calls of ``GPDMPrior.sample`` for 1000 particles, in ms."""
    prior = GPDMPrior(GPDMPriorModel(gpdm=model, normaliser=norm, fps=60.0, body_model="15-cone",
                                     dof_names=list(DOF_NAMES), sources=[], pose_step_rms=step_rms(clips)),
                      height=HeightOffset(0.0))  # as its published figures ran
    rng = np.random.default_rng(0)
    known = clips[0][:2]
    state = prior.start(known, PARTICLES, rng)
    hist = np.repeat(known[None, -1:], PARTICLES, axis=0)
    state = {k: v + 0.05 * rng.standard_normal(v.shape) if k == "latent" else v for k, v in state.items()}
    best = np.inf
    for _ in range(20):
        t0 = time.perf_counter()
        prior.sample(hist, 1, state, rng)
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=2000, help="training frames of the sparse model (default 2000)")
    ap.add_argument("--inducing", type=int, default=200, help="inducing frames (default 200)")
    ap.add_argument("--exact-frames", type=int, default=500, help="frames of the exact model's subset (default 500)")
    ap.add_argument("--iterations", type=int, default=300, help="L-BFGS iterations (default 300)")
    ap.add_argument("--methods", nargs="+", default=["dtc"], choices=SPARSE_METHODS,
                    help="sparse approximations to train on all frames (default dtc)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    loaded = load_training_clips([MOCAP / f"{c}.amc" for c in TRAIN + [TEST]], None, 60.0)
    clips, test = [r.poses for r in loaded[:-1]], loaded[-1].poses
    print(f"loaded and retargeted {len(loaded)} clips in {time.perf_counter() - t0:.1f} s", flush=True)
    keep = args.frames - sum(len(c) - 1 for c in clips[:-1])  # cut the long last clip (91_slow_walk)
    if not 2 < keep < len(clips[-1]):
        raise SystemExit(f"--frames must be in {sum(len(c) - 1 for c in clips[:-1]) + 3}.."
                         f"{sum(len(c) - 1 for c in clips)}")
    later = clips[-1][keep:keep + 301]  # each clip gives len - 1 feature frames
    clips[-1] = clips[-1][:keep + 1]
    normed, norm = clip_features(clips, DOF_NAMES)
    lengths = [len(f) for f in normed]
    Y = np.concatenate(normed)
    share = args.exact_frames // 3
    subset = [normed[TRAIN.index(c)][:share] for c in ("02/02_01", "07/07_01", "91/91_straight_walk")]
    tests = {"16_15": norm.transform(poses_to_invariant(test)[:-1]),
             "91_slow_walk later": norm.transform(poses_to_invariant(later)[:-1])}
    joints = [i for i, n in enumerate(norm.kept_names) if n not in
              ("forward_velocity", "lateral_velocity", "height", "pitch", "roll", "yaw_rate")]
    joint_std = norm.std[norm.keep][joints]
    print(f"training frames: {len(Y)} in {len(lengths)} clips {lengths}; exact subset: "
          f"{[len(f) for f in subset]} frames; tests: " + ", ".join(
              f"{k} {len(v)} frames ({len(v) - AHEAD} starts)" for k, v in tests.items()), flush=True)
    runs = {f"sparse {m}, all": (normed, args.inducing, m) for m in args.methods}
    runs.update({"exact, subset": (subset, 0, "dtc"), "sparse dtc, subset": (subset, args.inducing, "dtc")})
    rows = {}
    for name, (seqs, inducing, method) in runs.items():
        cfg = GPDMConfig(latent_dim=3, dynamics="linear+rbf", order=1, iterations=args.iterations,
                         inducing=inducing, sparse_method=method)
        model = train_gpdm(np.concatenate(seqs), [len(s) for s in seqs], cfg)
        h = model.objective_history
        row = {"frames": int(len(model.Y)), "inducing": 0 if model.active is None else int(len(model.active)),
               "iterations": args.iterations, "training_s": model.training_seconds,
               "objective_first_last": [h[0], h[-1]], "step_ms_1000_particles": step_ms(model, norm, clips),
               "forecast": {k: forecast(model, v, joints, joint_std) for k, v in tests.items()},
               "noise_precision": {"dynamics": float(model.log_alpha.detach()[-1].exp()),
                                   "observation": float(model.log_beta.detach()[2].exp())}}
        rows[name] = row
        print(f"{name:18s} {row['frames']:5d} frames, {row['inducing']:3d} inducing: trained in "
              f"{row['training_s']:6.1f} s ({args.iterations} it.), step {row['step_ms_1000_particles']:5.1f} ms; "
              "8-ahead RMS " + "; ".join(f"{k} {f['model']['rms_normalised']:.3f} "
                                         f"({f['model']['rms_joint_degrees']:.2f} deg)"
                                         for k, f in row["forecast"].items()), flush=True)
    hold = rows["exact, subset"]["forecast"]
    print(f"{'hold current pose':18s} 8-ahead RMS " + "; ".join(
        f"{k} {f['hold current pose']['rms_normalised']:.3f} ({f['hold current pose']['rms_joint_degrees']:.2f} deg)"
        for k, f in hold.items()))
    out = REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "gpdm_scale.json").write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
