"""How far CRBM model files' own rollouts stray from a held-out clip, h frames ahead (used to compare time-warped training clips).

    python benchmarks/rollout_error.py CLIP.amc NAME=MODEL.pt [NAME=MODEL.pt ...] [--every 3] [--seed 0]

From every ``--every``-th frame t0 of the clip (retargeted at 60 Hz) with 7 true frames of history, each model
samples the next 20 frames from the true past alone (one sample path per start, 30 Gibbs steps, no ground
diffusion; the start's own pending root step). Prints, for h = 1, 5 and 20, the mean marker error (mm) of the
sampled pose against the true one, with the root as sampled ("all") and with the true root put back ("pose":
the articulation alone), and the mean ground step per frame of the samples against the clip's.
"""
from __future__ import annotations

import argparse

import numpy as np

from priors.parts import GroundDiffusion

from priors.crbm.prior import CRBMPrior

from priors.crbm.file import load_crbm
from tracker.app.api import load_training_clips
from tracker.core.kinematics import markers
from tracker.core.representation import pending_step

HISTORY, HORIZON = 7, 20


def rollout(prior: CRBMPrior, past: np.ndarray, horizon: int, seed: int) -> np.ndarray:
    """Sampled futures ``S x horizon x D`` from pasts ``S x HISTORY x D`` (one batch row per start)."""
    n = prior.order
    hist = past[:, -n:]
    state = prior.start(past[0], len(past), np.random.default_rng(seed))
    state["step"] = np.stack([pending_step(p) for p in past])
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(horizon):
        x, state = prior.sample(hist, n, state, rng)
        hist = np.concatenate([hist[:, 1:], x[:, None]], axis=1)
        out.append(x)
    return np.stack(out, axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("clip")
    parser.add_argument("models", nargs="+", metavar="NAME=MODEL.pt")
    parser.add_argument("--every", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    clip = load_training_clips([args.clip], None, 60.0)[0]
    poses, body = clip.poses, clip.model
    starts = np.arange(HISTORY, len(poses) - HORIZON - 1, args.every)
    past = np.stack([poses[t - HISTORY:t] for t in starts])
    print("| model | " + " | ".join(f"h={h}: all / pose (mm), step (mm/frame, clip's)" for h in (1, 5, 20)) + " |")
    print("|---|---|---|---|")
    for item in args.models:
        name, _, path = item.partition("=")
        prior = CRBMPrior([load_crbm(path)], gibbs_steps=30, ground=GroundDiffusion(0.0))
        pred = rollout(prior, past, HORIZON, args.seed)
        cells = []
        for h in (1, 5, 20):
            true, guess = poses[starts + h - 1], pred[:, h - 1].copy()
            err = lambda a: float(np.mean(np.linalg.norm(markers(body, a) - markers(body, true), axis=-1)))
            whole = err(guess)
            guess[:, :6] = true[:, :6]
            step = np.linalg.norm(pred[:, h - 1, :2] - poses[starts - 1, :2], axis=1).mean() / h
            true_step = np.linalg.norm(true[:, :2] - poses[starts - 1, :2], axis=1).mean() / h
            cells.append(f"{whole:.1f} / {err(guess):.1f}, {step:.1f} ({true_step:.1f})")
        print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
