"""Train a small FCRBM on walks and runs and generate a walk -> run transition by blending the labels (Taylor &
Hinton 2009, Sec. 4.2), as a plot: the label weights, the ground speed, and the left knee and hip angles of the
generated motion, beside generation with the walk and the run label held fixed.

    python benchmarks/fcrbm_transition.py [--out docs/figures/fcrbm_transition.png] [--epochs 300] [--seed 0]

Training data (CMU, ../shared/mocap): walks 02_01, 02_02 (subject 2), 16_15 (subject 16); runs 02_03 (subject 2),
09_01, 09_02 (subject 9), 16_35 (subject 16), at 30 Hz. About a minute on two cores.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
MOCAP = REPO.parent / "shared" / "mocap" / "cmu"
WALKS = ["02/02_01.amc", "02/02_02.amc", "16/16_15.amc"]
RUNS = ["02/02_03.amc", "09/09_01.amc", "09/09_02.amc", "16/16_35.amc"]


def main() -> None:
    from matplotlib.figure import Figure

    from data_tools.motion.load import load_training_clips
    from priors.fcrbm.training import train_fcrbm
    from priors.settings import FCRBMConfig
    from priors.fcrbm.prior import generate, transition_styles
    from tracker.core.body import DOF_NAMES
    from tracker.core.representation import poses_to_invariant

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "docs" / "figures" / "fcrbm_transition.png"))
    ap.add_argument("--epochs", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fps", type=float, default=30.0)
    args = ap.parse_args()
    torch.set_num_threads(1)
    files = [MOCAP / f for f in WALKS + RUNS]
    clips = [c.poses for c in load_training_clips(files, None, args.fps)]
    labels = ["walk"] * len(WALKS) + ["run"] * len(RUNS)
    t0 = time.perf_counter()
    model = train_fcrbm(clips, labels, FCRBMConfig(order=3, hidden=100, factors=60, features=10, epochs=args.epochs),
                        args.fps, DOF_NAMES, sources=[str(f) for f in files], rng=np.random.default_rng(args.seed))
    print(f"trained in {time.perf_counter() - t0:.0f} s: {model.summary()}")
    T, switch, ramp = 240, 80, 60
    start = clips[0][:4]
    runs = {
        "walk label": transition_styles(2, 0, 0, T, 0, 1),
        "run label": transition_styles(2, 1, 1, T, 0, 1),
        f"walk -> run (blend over {ramp} frames from frame {switch})": transition_styles(2, 0, 1, T, switch, ramp),
    }
    motion = {name: generate(model, start, styles, np.random.default_rng(args.seed + 1))
              for name, styles in runs.items()}
    t = np.arange(T) / args.fps
    knee, hip = DOF_NAMES.index("left_knee_flexion"), 6  # left hip's first exp-map number
    fig = Figure(figsize=(8, 8), dpi=110)
    axes = fig.subplots(4, 1, sharex=True)
    blend = list(runs)[-1]
    axes[0].plot(t, runs[blend][:, 1], color="k")
    axes[0].set_ylabel("run label weight")
    axes[0].set_title(f"FCRBM generation at {args.fps:g} Hz (labels walk/run; {args.epochs} epochs)")
    for name, poses in motion.items():
        feats = poses_to_invariant(np.concatenate([start, poses]))[len(start):]
        speed = np.hypot(feats[:, 0], feats[:, 1]) * args.fps / 1000
        style = dict(lw=2.0, color="C3") if name == blend else dict(lw=1.0, ls="--")
        axes[1].plot(t, speed, label=name, **style)
        axes[2].plot(t, poses[:, knee], **style)
        axes[3].plot(t, poses[:, hip], **style)
        tail = speed[-60:].mean()
        print(f"{name}: mean ground speed over the last 2 s {tail:.2f} m/s, knee range "
              f"{np.ptp(poses[-60:, knee]):.2f} rad")
    for ax in axes[1:]:
        ax.axvspan(switch / args.fps, (switch + ramp) / args.fps, color="0.9")
    axes[1].set_ylabel("ground speed (m/s)")
    axes[1].legend(fontsize=7, loc="upper left")
    axes[2].set_ylabel("left knee (rad)")
    axes[3].set_ylabel("left hip (exp map x)")
    axes[3].set_xlabel("time (s)")
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out)
    print(f"-> {args.out}")


if __name__ == "__main__":
    main()
