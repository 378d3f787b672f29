"""Tracking experiments: wire a sequence, a prior, the likelihood and the filter together, and score the result.

This (with the command line) is the only place that knows concrete priors and
likelihoods; the filter sees their interfaces.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence as Seq

import numpy as np

from data_tools.sequence import Sequence
from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood, LikelihoodParams
from likelihoods.observations import DEFAULT_PARAMS, ObservationParams, Observations, observe
from tracker.engine.prior import MotionPrior
from tracker.core.errors import InputError
from tracker.engine.filter import FilterResult, FilterSettings, ParticleFilter
from tracker.core.kinematics import markers as model_markers
from tracker.core.metrics import marker_error


@dataclass
class TrackingRun:
    """One tracking run: estimates for every frame ``T x D`` (the known frames first, then the tracked ones),
    markers ``T x 15 x 3``, the tracked frame indices, per-frame marker error (mm) on the tracked frames when
    there is ground truth, and timings."""

    poses: np.ndarray
    markers: np.ndarray
    first_tracked: int
    errors: np.ndarray | None
    filter: FilterResult
    observation_seconds: float
    views: list[int]

    @property
    def mean_error(self) -> float | None:
        return None if self.errors is None else float(np.mean(self.errors))

    @property
    def seconds_per_frame(self) -> float:
        n = max(len(self.filter.seconds), 1)
        return (float(self.filter.seconds.sum()) + self.observation_seconds) / n


def frame_observations(seq: Sequence, frame: int, views: Seq[int],
                       params: ObservationParams = DEFAULT_PARAMS) -> Observations:
    """Silhouettes and edge maps of one frame in the chosen views (provided masks where the layout has them)."""
    images = [seq.image(frame, v) for v in views]
    masks = [seq.mask(frame, v) for v in views] if seq.mask_paths is not None else None
    backgrounds = None if masks is not None else [seq.background(v) for v in views]
    if backgrounds is not None and any(b is None for b in backgrounds):
        missing = [seq.rig[v].name for v, b in zip(views, backgrounds) if b is None]
        raise InputError(f"no background plate and no masks for camera(s) {', '.join(missing)}", seq.root)
    return observe(images, backgrounds, masks, params)


def known_start(seq: Sequence, n_known: int, init: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """The known poses ``n0 x D`` the filter starts from, and the first frame it tracks.

    ``init`` (``--init``) and the ground truth give the poses *of* frames
    ``0 .. n0-1`` (``n0 <= n_known``), so tracking starts at frame ``n0``. A
    PARSEC ``InitialPose.txt`` is the state the tracker starts from *before*
    frame 0 (as PARSEC uses it), so tracking starts at frame 0.
    """
    D = seq.model.n_dofs
    if init is not None:
        init = np.atleast_2d(np.asarray(init, float))
        if init.ndim != 2 or init.shape[1] != D:
            raise InputError(f"initial poses must be n x {D} for the {seq.model.name} model, got {init.shape}")
        if not np.all(np.isfinite(init)):
            raise InputError("initial poses contain NaN or infinite values")
        known = init[:n_known]
        return known, len(known)
    if seq.groundtruth is not None:
        known = seq.groundtruth.poses[:n_known]
        return known, len(known)
    if seq.initial_poses is not None:
        return seq.initial_poses[-n_known:], 0
    raise InputError("no ground truth and no initial pose: give initial poses (--init)", seq.root)


def track(seq: Sequence, prior: MotionPrior, settings: FilterSettings, seed: int, views: Seq[int] | None = None,
          n_frames: int | None = None, n_known: int = 2, init: np.ndarray | None = None,
          likelihood_params: LikelihoodParams = LikelihoodParams(),
          observation_params: ObservationParams = DEFAULT_PARAMS,
          on_frame: Callable[[int, float | None], None] | None = None) -> TrackingRun:
    """Track ``seq`` from its known first poses; frames ``0 .. n_frames-1`` (default: all)."""
    views = list(range(seq.n_views)) if views is None else list(views)
    rig = seq.rig.subset(views)
    T = seq.n_frames if n_frames is None else n_frames
    if not 1 <= T <= seq.n_frames:
        raise InputError(f"--frames {n_frames} is outside 1..{seq.n_frames} (the sequence's length)", seq.root)
    known, n0 = known_start(seq, n_known, init)
    if n0 >= T:
        raise InputError(f"nothing to track: {n0} known frame(s) and only {T} frame(s) requested", seq.root)
    likelihood = EdgeSilhouetteLikelihood(seq.model, rig, likelihood_params)
    gt = seq.groundtruth
    obs_time = [0.0]

    def frames():
        for k in range(n0, T):
            t0 = time.perf_counter()
            obs = frame_observations(seq, k, views, observation_params)
            obs_time[0] += time.perf_counter() - t0
            yield lambda poses, obs=obs: likelihood(poses, obs)

    def report(i: int, mean: np.ndarray) -> None:
        if on_frame is not None:
            err = None
            if gt is not None:
                err = float(marker_error(model_markers(seq.model, mean), gt.markers[n0 + i]))
            on_frame(n0 + i, err)

    pf = ParticleFilter(prior, settings, np.random.default_rng(seed))
    result = pf.run(known, frames(), report)
    poses = np.concatenate([known[:n0], result.mean_poses])
    est_markers = model_markers(seq.model, poses)
    errors = None
    if gt is not None:
        errors = marker_error(est_markers[n0:], gt.markers[n0:T])
    return TrackingRun(poses=poses, markers=est_markers, first_tracked=n0, errors=errors, filter=result,
                       observation_seconds=obs_time[0], views=views)


def read_poses_file(path: str | Path, what: str = "poses", model=None) -> np.ndarray:
    """The ``poses`` array ``T x D`` of an .npz (``estimates.npz``, ``--init``); with ``model`` its layout is
    checked too."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if "poses" not in z.files:
                raise InputError("no 'poses' array in the file", path)
            poses = np.asarray(z["poses"], float)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read {what} ({exc})", path) from None
    if model is not None:
        if poses.ndim != 2 or poses.shape[1] != model.n_dofs:
            raise InputError(f"{what} must be T x {model.n_dofs} for the {model.name} model, got {poses.shape}",
                             path)
        if not np.all(np.isfinite(poses)):
            raise InputError(f"{what} contain NaN or infinite values", path)
    return poses


def write_results(out: str | Path, run: TrackingRun, seq: Sequence, prior_name: str, particles: int, seed: int,
                  extra: dict | None = None) -> dict:
    """``OUTDIR/result.json`` and ``OUTDIR/estimates.npz`` as DESIGN.md specifies (plus documented extras)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tracked = list(range(run.first_tracked, len(run.poses)))
    result = {
        "prior": prior_name, "particles": particles, "views": run.views, "seed": seed, "frames": len(tracked),
        "mean_error_mm": run.mean_error,
        "std_error_mm": None if run.errors is None else float(np.std(run.errors)),
        "per_frame_error_mm": None if run.errors is None else [round(float(e), 3) for e in run.errors],
        "seconds_per_frame": run.seconds_per_frame,
        "tracked_frames": tracked, "first_tracked_frame": run.first_tracked,
        "sequence": str(seq.root), "model": seq.model.name,
        "mean_effective_sample_size": float(np.mean(run.filter.ess)),
        "recovered_frames": [run.first_tracked + k for k in run.filter.recovered],
        **(extra or {}),
    }
    (out / "result.json").write_text(json.dumps(result, indent=1))
    np.savez(out / "estimates.npz", poses=run.poses, markers=run.markers,
             best_poses=np.concatenate([run.poses[:run.first_tracked], run.filter.best_poses]))
    return result
