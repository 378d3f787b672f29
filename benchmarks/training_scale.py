"""What training costs on a large corpus, part by part, before any update runs.

    python benchmarks/training_scale.py [MOCAP ...] [--fps 60] [--updates 200]

Loads the clips (folders and patterns as ``train --mocap`` takes them; through the cache of converted clips),
then times each step that grows with the data: the invariant features and their normaliser with the windows
(:func:`priors.crbm.training.make_windows`), the pace spread that decides the pace input, a 10% validation split,
the history-noise scale, the FCRBM's label-balanced window count, and one epoch of about ``--updates`` mini-batch
updates of the CRBM and the FCRBM on one thread (the per-update cost, which the update budget multiplies). Prints
one line per step with its seconds and, for the frames tensor, its size. Default corpus: the shared ``mocap`` folder beside the checkout.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from data_tools.motion.load import load_training_clips  # noqa: E402
from priors.crbm.training import (history_noise_scale, make_windows, paces_vary, split_validation,  # noqa: E402
                                  train_crbm)
from priors.fcrbm.training import train_fcrbm, training_windows  # noqa: E402
from priors.settings import CRBMConfig, FCRBMConfig  # noqa: E402
from tracker.core.body import DOF_NAMES  # noqa: E402


def timed(label: str, call):
    """``call()``, printing its wall time (s) after ``label``."""
    t = time.perf_counter()
    out = call()
    print(f"{label:<48} {time.perf_counter() - t:8.2f} s")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mocap", nargs="*", default=[str(REPO.parent / "shared" / "mocap")])
    parser.add_argument("--fps", type=float, default=60.0)
    parser.add_argument("--updates", type=int, default=200)
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)
    clips = timed("load (retarget, or read the cache)", lambda: load_training_clips(args.mocap, None, args.fps))
    poses = [c.poses for c in clips]
    lengths = [len(p) for p in poses]
    print(f"{len(poses)} clips, {sum(lengths)} frames at {args.fps:g} Hz")
    data = timed("features, normaliser, windows (order 3)", lambda: make_windows(poses, 3, DOF_NAMES))
    print(f"frames tensor {tuple(data.frames.shape)}: {data.frames.numel() * 4 / 2 ** 20:.1f} MiB")
    timed("pace spread (the pace input's default)", lambda: paces_vary(poses, args.fps))
    timed("validation split (10%)", lambda: split_validation(data.starts, lengths, 3, 0.1))
    timed("history-noise scale", lambda: history_noise_scale(data))
    folders = [Path(c.source).parent.name for c in clips]
    timed("FCRBM balanced windows (a label per folder)", lambda: training_windows(lengths, folders, 3, True))
    # One epoch over the first clips that hold about --updates mini-batches of 100 windows.
    keep = int(np.searchsorted(np.cumsum([max(n - 4, 0) for n in lengths]), args.updates * 100)) + 1
    part, labels = poses[:keep], ["a" if i % 2 else "b" for i in range(min(keep, len(poses)))]
    n = -(-sum(max(len(p) - 4, 0) for p in part) // 100)
    crbm = timed(f"CRBM: one epoch, {n} updates (order 3)", lambda: train_crbm(
        part, CRBMConfig(epochs=1, updates=10 ** 9), args.fps, DOF_NAMES, rng=np.random.default_rng(0)))
    fcrbm = timed(f"FCRBM: one epoch (order 3, two labels)", lambda: train_fcrbm(
        part, labels, FCRBMConfig(epochs=1, updates=10 ** 9, balance=False), args.fps, DOF_NAMES,
        rng=np.random.default_rng(0)))
    print(f"per update (set-up included): CRBM {crbm.training_seconds / n * 1000:.1f} ms, "
          f"FCRBM {fcrbm.training_seconds / n * 1000:.1f} ms")


if __name__ == "__main__":
    main()
