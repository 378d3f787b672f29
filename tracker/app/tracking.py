"""Tracking a sequence: wire a sequence, a prior and a likelihood into the filter, and score the result.

:func:`track` is the one implementation behind ``tracker.track`` and
``pose-tracker track``; :class:`TrackingResult` holds everything a run
produced and writes ``result.json`` and ``estimates.npz`` (README, "Commands"),
so Python and the command line write the same files.
"""
from __future__ import annotations

import functools
import inspect
import json
import os
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence as Seq

import numpy as np

from data_tools.io.files import atomic_path, write_text_atomic
from data_tools.sequences.estimates import write_estimates
from data_tools.sequences.sequence import Sequence
from tracker.core.errors import InputError
from tracker.core.kinematics import markers as model_markers
from tracker.core.metrics import METRICS, PCK_THRESHOLD_MM, frame_metrics, marker_error
from tracker.engine.filter import FilterConfig, ParticleFilter
from tracker.engine.likelihood import Likelihood
from tracker.engine.prior import MotionPrior, summary_of
from tracker.engine.recording import DEFAULT_RECORD, RECORDERS, STAGES, FrameStep


@dataclass
class TrackingResult:
    """One tracking run.

    ``poses`` ``T x D`` and ``markers`` ``T x 15 x 3`` (mm) hold the known frames first, then the weighted-mean
    estimate of every tracked frame; ``best_poses`` likewise with the best particle; ``first_tracked`` is the
    first tracked frame; ``errors`` the per-frame marker error (mm) of the tracked frames, when the sequence
    has ground truth; ``records`` what the filter recorded per tracked frame (``ess``, timings, ...);
    ``settings`` every setting that produced the run (written to ``result.json``); ``summary_names`` names the
    entries of the prior's per-frame summary (``records["prior_summary"]``, e.g. the FCRBM's posterior over
    style labels), empty for a prior without one. ``frames`` is the number of frames the run was asked to cover
    (frames ``0 .. frames-1``, the known ones included; an interrupted run's partial result has fewer poses);
    ``per_frame_metrics`` every metric of :data:`tracker.core.metrics.METRICS` per tracked frame (name ->
    values), when the sequence has ground truth; ``invocation`` how the run was asked for (``{"function",
    "arguments"}`` for the API, ``{"argv"}`` for the command line), ``started`` and ``finished`` when (ISO 8601,
    UTC).
    """

    poses: np.ndarray
    markers: np.ndarray
    best_poses: np.ndarray
    first_tracked: int
    errors: np.ndarray | None
    records: dict[str, np.ndarray]
    settings: dict[str, Any] = field(default_factory=dict)
    summary_names: list[str] = field(default_factory=list)
    #: What the prior's summary is (:func:`~tracker.engine.prior.summary_of`).
    summary_kind: str = "posterior"
    frames: int | None = None
    per_frame_metrics: dict[str, np.ndarray] | None = None
    invocation: dict[str, Any] = field(default_factory=dict)
    started: str | None = None
    finished: str | None = None
    #: The checkpoint the run kept, removed once :meth:`save` has written the result (so a result that cannot be
    #: written, on a full disk say, leaves the run resumable); None without one.
    checkpoint: Path | None = field(default=None, repr=False)

    @property
    def tracked_frames(self) -> list[int]:
        return list(range(self.first_tracked, len(self.poses)))

    @property
    def mean_error(self) -> float | None:
        """Mean absolute MPJPE (the HumanEva marker error, ``metrics["mpjpe_abs"]``) over the tracked frames
        (mm), or None without ground truth."""
        return None if self.errors is None else float(np.mean(self.errors))

    @property
    def ess(self) -> np.ndarray:
        return self.records["ess"]

    @property
    def seconds_per_frame(self) -> float:
        """Wall time per tracked frame: reading, observations and the filter step, as far as they did not
        overlap (the sum of the three in results recorded without ``wall_seconds``)."""
        n = max(len(self.tracked_frames), 1)
        if "wall_seconds" in self.records:
            return float(self.records["wall_seconds"].sum()) / n
        return float(sum(self.records[f"{k}_seconds"].sum() for k in STAGES if f"{k}_seconds" in self.records)) / n

    @property
    def recovered_frames(self) -> list[int]:
        """Frames no particle explained (the filter re-diffused there)."""
        rec = self.records.get("recovered")
        return [] if rec is None else [self.first_tracked + int(k) for k in np.flatnonzero(rec)]

    @property
    def prior_per_frame(self) -> list[dict]:
        """Which model drew the poses, as spans ``{"first": frame, "last": frame, "model": label}``."""
        labels = self.records.get("prior_labels")
        spans: list[dict] = []
        for k, lab in enumerate([] if labels is None else labels):
            frame = self.first_tracked + k
            if spans and spans[-1]["model"] == lab:
                spans[-1]["last"] = frame
            else:
                spans.append({"first": frame, "last": frame, "model": str(lab)})
        return spans

    @property
    def prior_summary(self) -> dict[str, Any] | None:
        """The prior's per-frame summary as written to ``result.json``: ``names``, ``first_frame``, ``per_frame``
        (one row per tracked frame), ``kind`` (``"posterior"`` or ``"quantity"``) and, for a posterior,
        ``most_probable`` (the name of each row's largest entry); None without."""
        rows = self.records.get("prior_summary")
        if not self.summary_names or rows is None:
            return None
        rows = np.asarray(rows, float).reshape(-1, len(self.summary_names))
        out = {"names": list(self.summary_names), "first_frame": self.first_tracked, "kind": self.summary_kind,
               "per_frame": [[round(float(x), 4) for x in r] for r in rows]}
        if self.summary_kind == "posterior":
            out["most_probable"] = [self.summary_names[int(k)] for k in np.argmax(rows, axis=1)]
        return out

    def to_dict(self) -> dict[str, Any]:
        """The content of ``result.json``."""
        import tracker

        summary = self.prior_summary
        frames = len(self.poses) if self.frames is None else self.frames
        return {
            "version": tracker.__version__,
            "invocation": self.invocation, "started": self.started, "finished": self.finished,
            **self.settings,
            "frames": frames, "frames_known": self.first_tracked, "frames_tracked": len(self.tracked_frames),
            "complete": len(self.poses) >= frames,  # false for the partial result of an interrupted run
            "metrics": metrics_document(self.per_frame_metrics),
            "seconds_per_frame": self.seconds_per_frame,
            "tracked_frames": self.tracked_frames, "first_tracked_frame": self.first_tracked,
            "mean_effective_sample_size": float(np.mean(self.ess)) if "ess" in self.records else None,
            "recovered_frames": self.recovered_frames,
            "prior_per_frame": self.prior_per_frame,
            **({} if summary is None else {"prior_summary": summary}),
        }

    def save(self, out: str | Path, overwrite: bool = False) -> dict[str, Any]:
        """Write ``OUT/result.json`` and ``OUT/estimates.npz`` (each atomically), and for a prior with a per-frame
        summary (a style posterior, a pace) ``OUT/prior_summary.png``; returns the JSON content. A non-empty
        ``out`` is refused unless ``overwrite`` (then the files of this result replace those there), and so is
        the sequence's own folder or a folder inside it; a failed write (no space left, read-only, no permission)
        is one line naming the file and the cause. The run's checkpoint is removed once everything is written."""
        from data_tools.io.files import check_not_inside, check_output_folder

        out = check_output_folder(out, empty=not overwrite, overwrite_flag="overwrite=True")
        if self.settings.get("sequence"):
            check_not_inside(out, {"sequence folder": self.settings["sequence"]})
        result = self.to_dict()
        with atomic_path(out / "estimates.npz") as tmp:
            write_estimates(tmp, self.poses, self.markers, self.best_poses)
        write_text_atomic(out / "result.json", json.dumps(result, indent=1))
        if self.prior_summary is not None:
            from tracker.app.visualize import summary_plot

            kind = "posterior" if self.summary_kind == "posterior" else "posterior mean"
            summary_plot(out / "prior_summary.png", self.prior_summary,
                         f"{self.settings.get('prior', 'prior')}: {kind} per frame")
        else:  # an earlier result's plot would describe another run
            (out / "prior_summary.png").unlink(missing_ok=True)
        if self.checkpoint is not None:  # complete and written: nothing to resume
            Path(self.checkpoint).unlink(missing_ok=True)
        return result


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
        if len(init) == 0:
            raise InputError("initial poses are empty: give at least one pose")
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


def check_frames(seq: Sequence, n_frames: int | None, n_known: int, init: np.ndarray | None = None
                 ) -> tuple[int, np.ndarray, int]:
    """The frames a run tracks, checked: ``(T, known, n0)``, the run's length (``n_frames``, default the whole
    sequence) and the known start (:func:`known_start`). A length outside the sequence, a ``known_frames`` that is
    not a positive integer, or known frames that leave nothing to track are an :class:`InputError`."""
    if isinstance(n_known, bool) or not isinstance(n_known, (int, np.integer)) or n_known < 1:
        raise InputError(f"known frames must be an integer of at least 1, got {n_known!r}")
    T = seq.n_frames if n_frames is None else n_frames
    if isinstance(T, bool) or not isinstance(T, (int, np.integer)) or T < 1:
        raise InputError(f"frames must be an integer of at least 1, got {n_frames!r}", seq.root)
    if T > seq.n_frames:
        raise InputError(f"frames {T} is past the end of the sequence ({seq.n_frames} frames)", seq.root)
    known, n0 = known_start(seq, n_known, init)
    if n0 >= T:
        raise InputError(f"known frames {n_known} leave nothing to track: the run has {T} frame(s) and {n0} of them "
                         "would be known", seq.root)
    return int(T), known, n0


def check_views(views: Iterable[int] | None, n_views: int, source=None) -> list[int]:
    """Distinct camera indices within ``0 .. n_views-1`` (default: all)."""
    if views is None:
        return list(range(n_views))
    views = [int(v) for v in views]
    if not views or len(set(views)) != len(views):
        raise InputError(f"views must list distinct camera indices, got {views}", source)
    bad = [v for v in views if not 0 <= v < n_views]
    if bad:
        raise InputError(f"views {bad} out of range: the sequence has {n_views} cameras (0..{n_views - 1})", source)
    return views


def seed_description(seed: int | np.random.SeedSequence | np.random.Generator) -> Any:
    """How a run's seed is recorded in ``result.json``."""
    if isinstance(seed, np.random.SeedSequence):
        return {"entropy": seed.entropy, "spawn_key": list(seed.spawn_key)}
    if isinstance(seed, np.random.Generator):
        return "a caller's numpy Generator"
    return int(seed)


class TrackingInterrupted(Exception):
    """Ctrl-C during tracking: carries the partial result (the frames tracked so far) and where the checkpoint
    to resume from was written (None without a checkpoint path)."""

    def __init__(self, partial: TrackingResult, checkpoint: Path | None):
        super().__init__("tracking interrupted")
        self.partial = partial
        self.checkpoint = checkpoint


def run_tracking(seq: Sequence, prior: MotionPrior, likelihood: Likelihood, config: FilterConfig,
                 rng: np.random.Generator, views: Seq[int], n_frames: int | None = None, n_known: int = 2,
                 init: np.ndarray | None = None,
                 record: Iterable[str] | Mapping[str, Callable[[FrameStep], Any]] = DEFAULT_RECORD,
                 on_frame: Callable[[FrameStep, float | None], None] | None = None,
                 checkpoint: Path | None = None, checkpoint_every: int = 0, resume: bool = False,
                 fingerprint: dict | None = None) -> TrackingResult:
    """Track ``seq`` (frames ``0 .. n_frames-1``, default all) in ``views`` from its known first poses.

    ``on_frame(step, error_mm)`` is called after every tracked frame with the filter's
    :class:`~tracker.engine.recording.FrameStep` and that frame's marker error (None without ground truth).
    With ``checkpoint`` the filter's state is written there every ``checkpoint_every`` frames and on Ctrl-C
    (which raises :class:`TrackingInterrupted` with the partial result); ``resume`` continues from it to the
    result an uninterrupted run gives (its settings must match ``fingerprint``, and the sequence's files, the
    model files and the package version those of the interrupted run). The checkpoint stays until the result is
    saved (:meth:`TrackingResult.save`), so a result that cannot be written leaves the run resumable.
    """
    from tracker.app.checkpoint import load_checkpoint, save_checkpoint
    from tracker.app.threads import configured_threads, sync_torch_threads
    from tracker.engine.recording import Recording

    sync_torch_threads()  # a prior or likelihood built by the caller may have imported torch
    T, known, n0 = check_frames(seq, n_frames, n_known, init)
    gt = seq.groundtruth
    # The result needs the estimates and each frame's wall time (seconds_per_frame) whatever else is recorded.
    if isinstance(record, Mapping):
        record = {"mean_poses": lambda s: s.mean, "best_poses": lambda s: s.best,
                  "wall_seconds": RECORDERS["wall_seconds"], **dict(record)}
    else:
        record = list(record) + [k for k in ("mean_poses", "best_poses", "wall_seconds") if k not in record]
    summary = summary_of(prior)
    names = list(summary[0])
    if names and isinstance(record, dict):
        record.setdefault("prior_summary", lambda s: s.prior_summary)
    elif names and "prior_summary" not in record:
        record.append("prior_summary")
    recording = Recording(record)
    fingerprint = {**(fingerprint or {}), "frames": T, "known_frames": n_known}
    state = None
    inputs = None
    if resume and (checkpoint is None or not Path(checkpoint).exists()):
        raise InputError("no checkpoint to resume from", checkpoint)
    if checkpoint is not None:  # what the run reads, by content: a resume refuses inputs that changed since
        from tracker.app.checkpoint import input_fingerprint
        from data_tools.io.fingerprints import CACHE_NAME

        inputs = input_fingerprint(seq.root, fingerprint.get("prior_models", ()), Path(checkpoint).parent / CACHE_NAME)
    if resume:
        state, _ = load_checkpoint(checkpoint, fingerprint, recording, rng, inputs)

    def report(step: FrameStep) -> None:
        if on_frame is not None:
            err = None if gt is None else float(marker_error(model_markers(seq.model, step.mean),
                                                             gt.markers[step.frame]))
            on_frame(step, err)

    last = {"state": state, "rng": rng.bit_generator.state}

    def keep(st, rec) -> None:  # the state after a frame, with the generator's state at that moment
        last["state"], last["rng"] = st, rng.bit_generator.state
        if checkpoint is not None and checkpoint_every and st.tracked % checkpoint_every == 0:
            save_checkpoint(checkpoint, st, rec, last["rng"], fingerprint, inputs=inputs)

    first = n0 + (0 if state is None else state.tracked)
    pf = ParticleFilter(prior, likelihood, config, rng)
    workers = configured_threads() - 1  # with 2 or more: one thread filters while this one reads the next frame
    try:
        records = pf.run(known, (seq.frame(k, views) for k in range(first, T)), recording, report, state, keep,
                         workers=workers)
    except KeyboardInterrupt:
        done = 0 if last["state"] is None else last["state"].tracked
        for name in recording.values:  # drop a frame recorded after the last complete state
            recording.values[name] = recording.values[name][:done]
        if checkpoint is not None and last["state"] is not None:
            save_checkpoint(checkpoint, last["state"], recording, last["rng"], fingerprint, inputs=inputs)
        partial = _result(seq, known, n0, recording.result(), gt, T, summary) if done else None
        raise TrackingInterrupted(partial, checkpoint if last["state"] is not None else None) from None
    result = _result(seq, known, n0, records, gt, T, summary)
    result.checkpoint = checkpoint  # kept until the result is saved (TrackingResult.save removes it)
    return result


def _result(seq: Sequence, known: np.ndarray, n0: int, records: dict, gt, T: int,
            summary: tuple[Seq[str], str] = ((), "posterior")) -> TrackingResult:
    D = seq.model.n_dofs
    poses = np.concatenate([known[:n0], records["mean_poses"].reshape(-1, D)])
    best = np.concatenate([known[:n0], records["best_poses"].reshape(-1, D)])
    est_markers = model_markers(seq.model, poses)
    per_frame = None if gt is None else frame_metrics(est_markers[n0:], gt.markers[n0:len(poses)])
    return TrackingResult(poses=poses, markers=est_markers, best_poses=best, first_tracked=n0,
                          errors=None if per_frame is None else per_frame[METRICS[0].name], records=records,
                          summary_names=list(summary[0]), summary_kind=summary[1], frames=T,
                          per_frame_metrics=per_frame)


def metrics_document(per_frame: Mapping[str, np.ndarray] | None) -> dict[str, dict] | None:
    """``result.json``'s ``"metrics"``: for every metric of :data:`~tracker.core.metrics.METRICS` its ``unit``,
    ``mean`` and ``std`` over the tracked frames (ddof 0) and ``per_frame`` values (the 3DPCKs also their
    ``threshold_mm``); None without ground truth."""
    if per_frame is None:
        return None
    out = {}
    for m in METRICS:
        v = np.asarray(per_frame[m.name], float)
        out[m.name] = {"title": m.title, "unit": m.unit,
                       **({"threshold_mm": PCK_THRESHOLD_MM} if m.unit == "%" else {}),
                       "mean": float(v.mean()), "std": float(v.std()),
                       "per_frame": [round(float(x), 3 if m.unit == "mm" else 2) for x in v]}
    return out


def metrics_line(metrics: Mapping[str, dict] | None) -> str:
    """``result.json``'s ``"metrics"`` on one line: ``mpjpe_abs 25.0 ± 11.0 mm, ..., pck_rel 100.0%`` (mean ± std
    over the tracked frames for the errors, the mean for the 3DPCKs), or ``no ground truth to score``."""
    if not metrics:
        return "no ground truth to score"
    return ", ".join(f"{name} {m['mean']:.1f} ± {m['std']:.1f} mm" if m["unit"] == "mm" else f"{name} {m['mean']:.1f}%"
                     for name, m in metrics.items())


def utc_now() -> str:
    """The current time, ISO 8601 in UTC to the second (``2026-01-31T12:00:00+00:00``)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _described(value: Any) -> Any:
    """A JSON value that says what an argument of an API call was: plain values as they are, paths as text, a
    sequence by its folder, an array by its shape, a seed as :func:`seed_description` records it, anything else
    by its type."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, Sequence):
        return str(value.root)
    if isinstance(value, (np.random.SeedSequence, np.random.Generator)):
        return seed_description(value)
    if isinstance(value, np.ndarray):
        return f"array of shape {list(value.shape)}"
    if isinstance(value, Mapping):
        return {str(k): _described(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_described(v) for v in value]
    if callable(value):
        return f"callable {getattr(value, '__qualname__', type(value).__name__)}"
    return f"{type(value).__name__} (in memory)"


def records_call(function: Callable[..., TrackingResult]) -> Callable[..., TrackingResult]:
    """``function`` (the API's ``track``), whose result -- and the partial result of an interrupted run --
    records the call (``invocation``: ``tracker.<name>`` and the arguments the caller gave, keyword options
    flattened) and when it started and finished (:func:`utc_now`)."""
    signature = inspect.signature(function)

    @functools.wraps(function)
    def wrapper(*args, **kwargs) -> TrackingResult:
        bound = signature.bind(*args, **kwargs)
        given = dict(bound.arguments)
        for name, p in signature.parameters.items():  # **options: the options themselves, as they were written
            if p.kind is inspect.Parameter.VAR_KEYWORD:
                given.update(given.pop(name, {}))
        invocation = {"function": f"tracker.{function.__name__}", "arguments": _described(given)}
        started = utc_now()
        try:
            result = function(*args, **kwargs)
        except TrackingInterrupted as stop:
            if stop.partial is not None:
                stop.partial.invocation, stop.partial.started, stop.partial.finished = invocation, started, utc_now()
            raise
        result.invocation, result.started, result.finished = invocation, started, utc_now()
        return result

    return wrapper
