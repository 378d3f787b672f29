"""A tracking run kept in a folder: started, stopped (Ctrl-C, SIGTERM, a killed process) and continued.

:func:`track_into` is :func:`tracker.track` writing into an output folder: before the first frame it keeps the
run's request (:class:`TrackRequest`: the sequence, the prior, its model files, the settings and options, as
given) in ``OUT/track_arguments.json``; the filter's state is checkpointed in ``OUT/checkpoint.npz`` every
``checkpoint_every`` frames and at a stop, when the partial result is written too; the finished run writes
``result.json`` and ``estimates.npz`` (and the overlay video, if asked) and removes the request and the
checkpoint. :func:`resume_tracking` continues a stopped run from its folder alone, to the numbers an
uninterrupted run gives; :func:`track_into` given the same request again, into the folder of its unfinished run,
continues it likewise, and a different request there is refused (naming what differs) unless ``overwrite``.
``pose-tracker track`` and ``pose-tracker track --resume OUT`` are these two calls.

The checkpoint's own fingerprint (:mod:`tracker.app.checkpoint`) still guards the numbers: the request says
*what* to run again, the fingerprint that the state belongs to it.
"""
from __future__ import annotations

import json
import logging
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from data_tools.io.files import (check_not_inside, check_output_file, check_output_folder, first_missing,
                              undone_unless_started, write_text_atomic)
from tracker.app.tracking import TrackingInterrupted, TrackingResult
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

__all__ = ["REQUEST_FILE", "TrackRequest", "track_into", "resume_tracking", "run_in_folder", "saved_request",
           "finished_run", "run_sequence"]

#: The file that keeps an unfinished run's request in its output folder.
REQUEST_FILE = "track_arguments.json"
#: The format of :data:`REQUEST_FILE` (files of earlier versions hold the command line's parsed arguments).
REQUEST_FORMAT = "pose-tracker track request 1"


def _absolute(path: str | Path | None) -> str | None:
    return None if path is None else str(Path(path).expanduser().resolve())


@dataclass(frozen=True)
class TrackRequest:
    """What a tracking run was asked to do, as given (defaults are not filled in: a newer version's defaults
    apply to a request that left them out), with every path absolute.

    ``settings``: the run's settings (:data:`tracker.app.schema.TRACK_SETTINGS`; ``views`` a list of camera
    indices); ``options``: the prior's and the likelihood's options; ``init``: an ``.npz`` of initial poses;
    ``video``: an ``.mp4`` to draw the estimate over the first view into; ``plugins``: the plugins
    (:func:`tracker.app.plugins.import_plugin` specs) the prior or likelihood comes from."""

    sequence: str
    prior: str
    models: tuple[str, ...] = ()
    likelihood: str | None = None
    settings: Mapping[str, Any] = field(default_factory=dict)
    options: Mapping[str, Any] = field(default_factory=dict)
    init: str | None = None
    train_mocap: tuple[str, ...] | None = None
    video: str | None = None
    plugins: tuple[str, ...] = ()

    @classmethod
    def of(cls, sequence: str | Path, prior: str, *, models: Iterable[str | Path] = (), likelihood: str | None = None,
           init: str | Path | None = None, train_mocap: Iterable[str | Path] | None = None,
           video: str | Path | None = None, plugins: Iterable[str] = (), **settings) -> "TrackRequest":
        """A request from :func:`tracker.track`'s arguments (``settings``: the run's settings and the plugins'
        options, told apart here), its paths made absolute. A prior's options that name model files of their
        own (a mixture's components) have theirs made absolute by the prior's registry entry."""
        from tracker.app.plugins import prior_entry
        from tracker.app.schema import TRACK_SETTINGS

        if not isinstance(prior, str):
            raise InputError("a run kept in a folder takes its prior by name (a prior object cannot be saved to "
                             "resume it)")
        run = {k: v for k, v in settings.items() if k in TRACK_SETTINGS}
        options = {k: v for k, v in settings.items() if k not in TRACK_SETTINGS}
        options = prior_entry(prior).located(options, _absolute)  # model files the options name themselves
        return cls(sequence=_absolute(sequence), prior=prior, models=tuple(_absolute(m) for m in models),
                   likelihood=likelihood, settings=run, options=options, init=_absolute(init),
                   train_mocap=None if train_mocap is None else tuple(_absolute(m) for m in train_mocap),
                   video=_absolute(video),
                   plugins=tuple(str(Path(p).resolve()) if p.endswith(".py") else p for p in plugins))

    def as_json(self) -> dict[str, Any]:
        """The request as :data:`REQUEST_FILE` holds it."""
        return json.loads(json.dumps({"format": REQUEST_FORMAT, **asdict(self)}))

    @classmethod
    def from_json(cls, data: Mapping[str, Any], path: Path) -> "TrackRequest":
        """The request :meth:`as_json` wrote; anything else is an :class:`InputError` naming ``path``."""
        if data.get("format") != REQUEST_FORMAT:
            raise InputError(f"not a saved track request of this version (format {data.get('format')!r})", path)
        kinds = {"sequence": str, "prior": str, "models": list, "likelihood": (str, type(None)),
                 "settings": dict, "options": dict, "init": (str, type(None)), "train_mocap": (list, type(None)),
                 "video": (str, type(None)), "plugins": list}
        fields = {k: v for k, v in data.items() if k != "format"}
        wrong = sorted(k for k, v in fields.items() if k not in kinds or not isinstance(v, kinds[k]))
        missing = sorted({"sequence", "prior"} - set(fields))
        if wrong or missing:
            raise InputError(f"saved track request is malformed ({', '.join(wrong + missing)})", path)
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()})

    @classmethod
    def from_earlier(cls, saved: Mapping[str, Any], path: Path) -> "TrackRequest":
        """The request of a file an earlier version kept: the command line's parsed arguments (``model``,
        ``plugin``, ``views`` as text, each option under its own name, None where not given)."""
        from tracker.app.schema import TRACK_SETTINGS

        fields = {"sequence", "prior", "model", "likelihood", "views", "init", "train_mocap", "video", "plugin",
                  "overwrite", "out", "command", "resume", "threads", "quiet", "verbose", "argv"}
        try:
            views = saved.get("views")
            if isinstance(views, str):
                views = [int(v) for v in views.split(",") if v.strip()]
            settings = {k: saved[k] for k in TRACK_SETTINGS if k != "views" and saved.get(k) is not None}
            options = {k: v for k, v in saved.items() if k not in fields and k not in TRACK_SETTINGS and v is not None}
            return cls.of(saved["sequence"], saved["prior"], models=saved.get("model") or (),
                          likelihood=saved.get("likelihood"), init=saved.get("init"),
                          train_mocap=saved.get("train_mocap"), video=saved.get("video"),
                          plugins=saved.get("plugin") or (), views=views, **settings, **options)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"saved track arguments are malformed ({type(exc).__name__}: {exc})", path) from None

    def differences(self, other: "TrackRequest") -> list[str]:
        """The names (request fields, settings and options) in which ``other`` asks for something else; a setting
        left out counts as its default (:mod:`tracker.app.schema`), so that the command line's request, which
        names every setting, and Python's, which names those given, agree where they ask for the same run."""
        from tracker.app.schema import defaults

        def flat(r: TrackRequest) -> dict:
            d = r.as_json()
            settings = {**defaults(), **{k: v for k, v in d["settings"].items() if v is not None}}
            return {**{k: v for k, v in d.items() if k not in ("settings", "options")},
                    **json.loads(json.dumps(settings)), **d["options"]}

        a, b = flat(self), flat(other)
        return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))


def saved_request(out: str | Path) -> TrackRequest | None:
    """The request of the unfinished run in ``out`` (None where none is kept), its plugins imported; also one an
    earlier version kept (:meth:`TrackRequest.from_earlier`)."""
    from data_tools.io.textfiles import read_json
    from tracker.app.plugins import import_plugin

    path = Path(out) / REQUEST_FILE
    if not path.is_file():
        return None
    data = read_json(path, "saved track request")
    if not isinstance(data, dict):
        raise InputError("saved track request is not a JSON object", path)
    plugins = data.get("plugins", data.get("plugin", []))
    if not isinstance(plugins, list) or not all(isinstance(p, str) for p in plugins):
        raise InputError("saved track request is malformed (plugins)", path)
    for spec in plugins:  # before the request's prior is looked up
        import_plugin(spec)
    if "format" not in data:
        return TrackRequest.from_earlier(data, path)
    return TrackRequest.from_json(data, path)


class TrackingStopped(TrackingInterrupted):
    """A run in a folder stopped (Ctrl-C, SIGTERM). ``partial``: the frames tracked, written to the folder
    (None before the first frame); ``resumable``: the folder keeps what :func:`resume_tracking` needs (False: it
    was removed again, nothing was kept)."""

    def __init__(self, partial: TrackingResult | None, checkpoint: Path | None, out: Path, resumable: bool):
        super().__init__(partial, checkpoint)  # type: ignore[arg-type]
        self.out = out
        self.resumable = resumable


def track_into(out: str | Path, sequence: str | Path, prior: str, *, models: Iterable[str | Path] = (),
               likelihood: str | None = None, init: str | Path | None = None,
               train_mocap: Iterable[str | Path] | None = None, video: str | Path | None = None,
               overwrite: bool = False, on_frame: Callable | None = None, **settings) -> TrackingResult:
    """Track as :func:`tracker.track` does, into the folder ``out``, resumably (see the module's text).

    ``sequence`` is a sequence folder and ``init`` an ``.npz`` of initial poses (paths, so that a stopped run can
    be continued from its folder alone); ``video`` an ``.mp4`` to draw the estimate over the first view into.
    A non-empty ``out`` is refused unless ``overwrite`` or it holds this same request, unfinished (then the run
    continues). A stop raises :class:`TrackingStopped`."""
    request = TrackRequest.of(sequence, prior, models=models, likelihood=likelihood, init=init,
                              train_mocap=train_mocap, video=video, **settings)
    return run_in_folder(request, out, overwrite=overwrite, on_frame=on_frame)


def resume_tracking(out: str | Path, on_frame: Callable | None = None) -> TrackingResult:
    """Continue the stopped run in ``out`` from its checkpoint (from its first frame where it stopped before its
    first checkpoint) to the result an uninterrupted run gives."""
    request = saved_request(out)
    if request is None:
        raise InputError(f"no interrupted run to resume here (no {REQUEST_FILE})", out)
    return run_in_folder(request, out, resume=True, on_frame=on_frame)


def run_in_folder(request: TrackRequest, out: str | Path, *, overwrite: bool = False, resume: bool = False,
                  on_frame: Callable | None = None, on_start: Callable[[int], None] | None = None,
                  invocation: dict | None = None, overwrite_flag: str = "overwrite=True",
                  resume_command: str | None = None) -> TrackingResult:
    """Run ``request`` into ``out`` (:func:`track_into`; ``resume``: continue the run kept there, as
    :func:`resume_tracking`). ``on_start(frames)`` is told, once every input is checked, how many frames the
    run tracks; ``on_frame(step, error_mm)`` sees each as :func:`tracker.track`'s does. ``invocation`` is what
    ``result.json`` records as the call (default the call of :func:`tracker.track` the request makes);
    ``overwrite_flag`` and ``resume_command`` how a refusal says to replace the folder and to continue its run
    (default: as Python says them)."""
    from tracker.app import api

    out = Path(out)
    if not resume and not overwrite:
        kept = saved_request(out)
        if kept is not None:
            differ = kept.differences(request)
            if differ:
                resume_how = resume_command or f"tracker.resume_tracking({str(out)!r})"
                raise InputError(f"the output folder holds an unfinished run of other arguments ({', '.join(differ)}): "
                                 f"continue it with {resume_how}, or pass {overwrite_flag} to start this one in its "
                                 "place", out)
            log.info(f"{out} holds this run, unfinished: continuing it")
            resume = True
    out = check_output_folder(out, empty=not (overwrite or resume), overwrite_flag=overwrite_flag)
    check_not_inside(out, {"sequence folder": request.sequence})
    if request.video:
        check_output_file(request.video, "the video", (".mp4",), new=not (overwrite or resume),
                          overwrite_flag=overwrite_flag)
        check_not_inside(request.video, {"sequence folder": request.sequence})
    checkpoint = out / "checkpoint.npz"
    try:
        with undone_unless_started(first_missing(out)) as work:  # refused or stopped before the first frame:
            # nothing stays behind (a resumed run keeps its request)
            work["started"] = resume
            seq, init, frames = _checked_inputs(request)
            if not resume:
                checkpoint.unlink(missing_ok=True)  # an earlier run's, in a folder given overwrite
                write_text_atomic(out / REQUEST_FILE, json.dumps(request.as_json(), indent=1))
            elif not checkpoint.exists():  # stopped before its first checkpoint (or killed): the whole run again
                log.info(f"no checkpoint in {out}: tracking from the first frame with the saved arguments")
            if on_start is not None:
                on_start(frames)

            def frame(step, error: float | None) -> None:
                work["started"] = True
                if on_frame is not None:
                    on_frame(step, error)

            try:
                run = api.track(seq, request.prior, models=request.models, likelihood=request.likelihood,
                                init=init, train_mocap=request.train_mocap, on_frame=frame,
                                checkpoint=checkpoint, resume=resume and checkpoint.exists(),
                                **request.settings, **request.options)
            except TrackingInterrupted as stop:
                if stop.partial is not None:
                    if invocation is not None:
                        stop.partial.invocation = invocation
                    stop.partial.save(out, overwrite=True)
                if stop.partial is None and not resume:
                    raise KeyboardInterrupt from None  # as if never started: the block removes what it made
                raise TrackingStopped(stop.partial, checkpoint, out, resumable=True) from None
    except KeyboardInterrupt:  # before the first frame
        raise TrackingStopped(None, None, out, resumable=resume) from None
    if invocation is not None:
        run.invocation = invocation
    run.save(out, overwrite=True)
    (out / REQUEST_FILE).unlink(missing_ok=True)
    if request.video:
        from tracker.app.visualize import overlay_frames, write_video

        write_video(Path(request.video), overlay_frames(seq, run.poses, list(run.settings["views"]), run.errors,
                                                        run.first_tracked, estimate_name=request.prior),
                    seq.fps or 25.0)
        log.info(f"overlay video -> {request.video}")
    return run


def _checked_inputs(request: TrackRequest):
    """The request's sequence and initial poses, read and checked (with its views and frames) before anything is
    written, and how many frames the run tracks."""
    from data_tools.sequences.estimates import read_poses_file
    from tracker.app.api import load_sequence, run_settings
    from tracker.app.tracking import check_frames

    seq = load_sequence(request.sequence)
    init = read_poses_file(request.init, "initial poses", seq.model) if request.init else None
    settings = run_settings(request.settings, seq)
    last, _, first = check_frames(seq, settings["frames"], settings["known_frames"], init)
    return seq, init, last - first


def finished_run(run: str | Path) -> tuple[Path, dict]:
    """A tracked run's folder: its ``estimates.npz`` and its ``result.json`` (empty when absent); a folder without
    estimates is an :class:`InputError`."""
    from data_tools.io.textfiles import read_json

    folder = Path(run)
    if not (folder / "estimates.npz").is_file():
        raise InputError("not a tracked run: no estimates.npz", folder)
    result = read_json(folder / "result.json", "result.json") if (folder / "result.json").is_file() else {}
    return folder / "estimates.npz", result if isinstance(result, dict) else {}


def run_sequence(result: Mapping[str, Any], given: str | Path | None, run: str | Path):
    """The sequence a run tracked: ``given``, else the one its ``result.json`` names."""
    from data_tools.sequences.sequence import read_sequence

    path = given or result.get("sequence")
    if not path:
        raise InputError("result.json names no sequence: give --sequence DIR", run)
    return read_sequence(path)
