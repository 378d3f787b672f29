"""The CRBM's one-step bias on a person it was not trained on (issue 13, round 20 of docs/unseen_people.md).

    python benchmarks/one_step_bias.py [--fold 02] [--offsets 0,0.05,0.1,0.2] [--samples 200] [--every 7]

Trains the paced CRBM-3 of a leave-one-subject-out fold (the walks of the other subjects, each retargeted with its
own skeleton; `train`'s settings, training seed 0) once per posture offset (`train --posture-offset`, rad), then,
from the left-out walker's true history at every ``--every``-th frame, draws ``--samples`` next poses and
measures their pelvis-relative marker error (mm) against the true next frame: the median and the best sample,
averaged over the frames. The zero-velocity random walk (its scale from the same training walks) is the reference.
A prior whose best sample is far from the truth cannot be rescued by the likelihood in that frame.

Also prints, for each model, the share of a 0.1 rad shift of every posture angle of the left-out walk that its
one-step prediction (the free-energy best guess) keeps: 1 keeps the person's posture, 0 pulls it back to the
training subjects'.

`benchmarks/rollout_error.py` measures the error of one sample path many steps ahead; this script the spread of
one step's samples (their median and their best), which is what the likelihood can choose from. Folds 02 and 07
are the tuning folds; the others are test folds (a measurement there is a diagnostic, not a
choice). Run by hand (a few minutes per offset on 2 cores); prints a Markdown table.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from priors.crbm import CRBMPrior  # noqa: E402
from priors.random_walk import ZeroVelocityPrior  # noqa: E402
from tracker.app.api import load_clip, train  # noqa: E402
from tracker.core.kinematics import markers  # noqa: E402
from tracker.core.metrics import marker_error  # noqa: E402
from tracker.core.representation import poses_to_invariant, posture_features, step_rms  # noqa: E402

CMU = REPO.parent / "shared" / "mocap" / "cmu"
WALKS = {"02": ["02/02_01.amc", "02/02_02.amc"], "07": ["07/07_01.amc", "07/07_02.amc", "07/07_09.amc", "07/07_10.amc"],
         "16": ["16/16_15.amc"], "91": ["91/91_straight_walk.amc"]}
LEFT_OUT = {"02": "02/02_01.amc", "07": "07/07_11.amc", "16": "16/16_15.amc", "91": "91/91_straight_walk.amc"}


def one_step_errors(prior, poses: np.ndarray, truth_markers: np.ndarray, model, history: int, samples: int,
                    every: int) -> tuple[float, float]:
    """Mean over frames of the median and of the least pelvis-relative marker error (mm) of ``samples`` one-step
    samples of ``prior`` from the true ``history`` frames before each ``every``-th frame of ``poses``."""
    medians, best = [], []
    for t in range(history, len(poses), every):
        rng = np.random.default_rng(t)
        known = poses[t - history:t]
        state = prior.start(known, samples, rng)
        x, _ = prior.sample(np.repeat(known[None], samples, axis=0), history, state, rng)
        err = marker_error(markers(model, x), truth_markers[t:t + 1], root_aligned=True)
        medians.append(np.median(err))
        best.append(err.min())
    return float(np.mean(medians)), float(np.mean(best))


def posture_kept(crbm_model, poses: np.ndarray, shift: float = 0.1) -> float:
    """The share of a ``shift`` rad offset of every posture angle that the model's one-step best guess keeps."""
    feats = poses_to_invariant(poses)[:-1]
    posture = posture_features(feats.shape[1])
    shifted = feats.copy()
    shifted[:, posture] += shift
    n = crbm_model.order
    out = []
    for f in (feats, shifted):
        z = crbm_model.normaliser.transform(f)
        hist = np.stack([z[i:len(z) - n + i] for i in range(n)], axis=1).reshape(len(z) - n, -1)
        if crbm_model.config.pace_input:  # the training walks' mean pace
            hist = np.concatenate([crbm_model.pace_input(np.full(len(hist), crbm_model.pace_label[0])), hist], 1)
        guess = crbm_model.crbm.best_guess(torch.tensor(hist, dtype=torch.float32)).numpy()
        out.append(crbm_model.normaliser.inverse(guess))
    return float((out[1] - out[0])[:, posture].mean() / shift)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fold", choices=sorted(LEFT_OUT), default="02", help="the left-out subject (default 02)")
    ap.add_argument("--offsets", default="0,0.05,0.1,0.2", help="posture offsets to train with, rad")
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--every", type=int, default=7)
    args = ap.parse_args()
    torch.set_num_threads(1)
    training = [CMU / f for s, files in WALKS.items() if s != args.fold for f in files]
    test = load_clip(CMU / LEFT_OUT[args.fold])  # markers: the mocap's joints, the tracking error's ground truth
    zv = ZeroVelocityPrior(step_rms([load_clip(f).poses for f in training]))  # as `compare` scales the baseline
    rows = [("zero-velocity (random walk)",
             one_step_errors(zv, test.poses, test.markers, test.model, 1, args.samples, args.every), None)]
    for offset in (float(x) for x in args.offsets.split(",")):
        model = train("crbm", training, fps=60, rng=0, order=3, posture_offset=offset)
        prior = CRBMPrior([model], height_spread=0.0)  # the order-3 model: every history frame is real
        rows.append((f"CRBM-3, posture offset {offset:g}",
                     one_step_errors(prior, test.poses, test.markers, test.model, 3, args.samples, args.every),
                     posture_kept(model, test.poses)))
    print(f"One step from the true history of {LEFT_OUT[args.fold]} (fold {args.fold}), {args.samples} samples at "
          f"every {args.every}th frame; pelvis-relative marker error, mm\n")
    print("| prior | median | best sample | share of a 0.1 rad posture shift kept |\n|---|---|---|---|")
    for name, (median, best), kept in rows:
        print(f"| {name} | {median:.1f} | {best:.1f} | {'' if kept is None else f'{kept:.2f}'} |")


if __name__ == "__main__":
    main()
