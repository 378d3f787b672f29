"""Tracking with 2-D keypoints on synthetic sequences with exact ground truth (run by hand).

The keypoints come from the detector noise model (:mod:`data_tools.vision.keypoints.simulate`; its defaults unless
``--noise`` says otherwise, the detections drawn with ``--noise-seed``) at the sequence's true poses; the start is
fitted to them (:func:`tracker.app.keypoint_start.initialise_from_keypoints`: the body measured, as a user's
would be) and each likelihood tracks from it with ``--prior``. Printed per likelihood: the mean distance over
the 12 limb joints (mm; mean ± std over the seeds), over all 15 markers, over the limb joints after one rigid
alignment of the whole run (the measure with one camera, whose depth is the body's size), the worst frame, and
seconds per frame; with two or more views first the robust triangulation of the same keypoints, median-filtered
over 5 frames (:mod:`data_tools.vision.keypoints.triangulate`), over the limb joints.

The sequences of ``docs/results.md`` (CMU clips from ``../shared/mocap/cmu``)::

    pose-tracker synth --mocap ../shared/mocap/cmu/16/16_15.amc --out walk16 --frames 100 --seed 1   # tuning
    pose-tracker synth --mocap ../shared/mocap/cmu/49/49_18.amc --out motion49 --frames 100 --seed 2
    pose-tracker synth --mocap ../shared/mocap/cmu/bvh/11_01.bvh --out kick11 --frames 100 --seed 3
    python benchmarks/keypoint_tracking.py kick11 --views 0,1,2,3 --prior mixture --seeds 0,1,2 \\
        --likelihoods 'edge-silhouette;keypoints+edge-silhouette:{"keypoint_refine":0};keypoints+edge-silhouette'

It writes ``SEQ/keypoints/keypoints.npz`` (replacing any there): run it on a copy of a sequence of your own.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import tracker  # noqa: E402
from data_tools.sequences.keypoint_file import write_keypoints  # noqa: E402
from data_tools.sequences.sequence import read_sequence  # noqa: E402
from data_tools.vision.keypoints.simulate import DetectorNoise, simulate_sequence_keypoints  # noqa: E402
from data_tools.vision.keypoints.triangulate import median_filter, triangulate_keypoints  # noqa: E402
from tracker.app.keypoint_start import initialise_from_keypoints  # noqa: E402
from tracker.core.keypoints import KEYPOINT_INDEX  # noqa: E402

LIMBS = ("left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
         "left_hip", "left_knee", "left_ankle", "right_hip", "right_knee", "right_ankle")


def rigidly_aligned(points: np.ndarray, onto: np.ndarray) -> np.ndarray:
    """``points`` ``N x 3`` moved by the one rotation and translation that brings them nearest ``onto`` (Kabsch;
    rows with a NaN left out of the fit)."""
    ok = np.isfinite(points).all(axis=1) & np.isfinite(onto).all(axis=1)
    a0, b0 = points[ok].mean(axis=0), onto[ok].mean(axis=0)
    U, _, Vt = np.linalg.svd((points[ok] - a0).T @ (onto[ok] - b0))
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
    return (points - a0) @ R.T + b0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sequence", help="a synthetic sequence folder (with groundtruth.npz)")
    p.add_argument("--views", default="0,1,2,3")
    p.add_argument("--likelihoods", default="keypoints+edge-silhouette",
                   help="';'-separated likelihoods, each optionally NAME:{JSON options}")
    p.add_argument("--prior", default="mixture")
    p.add_argument("--frames", type=int, default=100)
    p.add_argument("--particles", type=int, default=1000)
    p.add_argument("--seeds", default="0,1,2")
    p.add_argument("--noise", default="{}", help="DetectorNoise settings as JSON")
    p.add_argument("--noise-seed", type=int, default=100)
    a = p.parse_args()
    views = [int(v) for v in a.views.split(",")]
    seq = read_sequence(a.sequence)
    write_keypoints(seq.root, simulate_sequence_keypoints(seq, np.random.default_rng(a.noise_seed),
                                                          DetectorNoise(**json.loads(a.noise))))
    seq = read_sequence(a.sequence)
    F = min(a.frames, seq.n_frames)
    truth = seq.groundtruth.markers[:F]
    limbs = [seq.model.marker_names.index(n) for n in LIMBS]
    if len(views) >= 2:
        found = triangulate_keypoints(seq.rig.subset(views), seq.keypoints.points[:F, views]).points
        found = median_filter(found)[:, [KEYPOINT_INDEX[n] for n in LIMBS]]
        print(f"{'triangulated':48s} limbs {np.nanmean(np.linalg.norm(found - truth[:, limbs], axis=-1)):6.1f}")
    started = time.perf_counter()
    start = initialise_from_keypoints(seq, views)
    start_seconds = time.perf_counter() - started
    seq.model = start.model  # the measured body, as a user's run has it
    for entry in a.likelihoods.split(";"):
        name, _, options = entry.partition(":")
        options = json.loads(options) if options else {}
        rows = []
        for seed in (int(s) for s in a.seeds.split(",")):
            run = tracker.track(seq, a.prior, likelihood=name, init=start.poses, views=views, frames=F, seed=seed,
                                particles=a.particles, **options)
            est = run.markers[:F]
            error = np.linalg.norm(est - truth, axis=-1)
            aligned = rigidly_aligned(est.reshape(-1, 3), truth.reshape(-1, 3)).reshape(est.shape)
            rows.append((error[:, limbs].mean(), error.mean(),
                         np.linalg.norm(aligned - truth, axis=-1)[:, limbs].mean(),
                         error[:, limbs].mean(axis=1).max(), run.seconds_per_frame))
        r = np.array(rows)
        print(f"{entry:48s} limbs {r[:, 0].mean():6.1f} ± {r[:, 0].std():4.1f}  all15 {r[:, 1].mean():6.1f}  "
              f"aligned limbs {r[:, 2].mean():6.1f}  worst frame {r[:, 3].mean():6.1f}  "
              f"{r[:, 4].mean():.3f} s/frame  (start {start_seconds:.1f} s)", flush=True)


if __name__ == "__main__":
    main()
