"""Command line: ``pose-tracker <command>`` (also ``python -m tracker <command>``; the contract: README,
"Commands").

The command line only parses arguments (:mod:`tracker.app.parser`) and calls the public API
(:mod:`tracker.app.api`). Every bad input ends with a one-line reason on stderr, ``pose-tracker: error: ...``, and
exit status 2. Informational lines (what was read, chosen and written, timings, progress) go through
:mod:`logging` (:mod:`tracker.app.console`: ``--quiet``, ``--verbose``); what says how well a command's job went
goes to stdout: track's and demo's errors, compare's tables, train's fit, convert's retarget residual.
"""
from __future__ import annotations

import argparse
import gc
import json
import logging
import shlex
import sys
from pathlib import Path
from typing import NoReturn, Sequence

import numpy as np

from data_tools.files import (atomic_path, check_not_inside, check_output_file, check_output_folder)
from tracker.app.console import (PROG, close_bars, configure_logging, error_line, interrupted_status, invoked_as,
                                 progress_bar, shows_progress, stop_signals, verbosity)
from tracker.app.parser import UNNAMED_LIKELIHOOD, build_parser, given_options, parse_arguments
from tracker.app.plugins import import_plugin, likelihood_entry, prior_entry
from tracker.app.schema import TRACK_SETTINGS
from tracker.app.threads import set_threads
from tracker.app.video_commands import COMMANDS as VIDEO_COMMANDS
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

def cmd_convert(args: argparse.Namespace) -> int:
    from data_tools.clip_io import save_converted_clip
    from tracker.app.api import read_clip

    out = check_output_file(args.out, "the output", (".npz",), new=not args.overwrite)
    check_not_inside(out, {"mocap file": args.mocap, **({"skeleton": args.skeleton} if args.skeleton else {})})
    clip, result = read_clip(args.mocap, args.skeleton, args.fps, args.length_unit, args.joint_map)
    with atomic_path(out) as tmp:
        save_converted_clip(result, tmp)
    print(f"{Path(args.mocap).name}: {clip.summary()}; {len(result.poses)} frames at {result.fps:g} fps, "
          f"mean retarget residual {result.mean_residual:.2f} mm -> {out}")  # the residual: how well it went
    return 0


def _shown(path: str) -> str:
    """``path`` relative to the working folder where it lies below it, else as it is."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return path


def cmd_corpus(args: argparse.Namespace) -> int:
    from data_tools.corpus import survey
    from tracker.app.plugins import load_plugins

    load_plugins()  # the readers of installed plugins
    entries = survey(args.paths, args.labels)
    clips = [e for e in entries if e.refused is None]
    refused = [e for e in entries if e.refused is not None]
    frames = sum(e.frames for e in clips)
    seconds = sum(e.seconds for e in clips)
    rates: dict[float, int] = {}
    for e in clips:
        rates[e.fps] = rates.get(e.fps, 0) + 1
    by_rate = ", ".join(f"{n} at {r:g} Hz" for r, n in sorted(rates.items()))
    if args.json:
        print(json.dumps({"clips": [{**e.as_dict(), "file": _shown(e.path)} for e in clips],
                          "refused": [{"file": _shown(e.path), "reason": e.refused} for e in refused],
                          "total": {"clips": len(clips), "frames": frames, "seconds": round(seconds, 3),
                                    "rates": {f"{r:g}": n for r, n in sorted(rates.items())},
                                    "refused": len(refused)}}, indent=1))
    else:
        rows = [(_shown(e.path), str(e.frames), f"{e.fps:g}", f"{e.seconds:.1f}", e.naming, e.unit, e.up,
                 " ".join(f"{k}={v}" for k, v in e.labels.items())) for e in clips]
        head = ("file", "frames", "Hz", "seconds", "naming", "length unit", "up", "labels")
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
        for row in [head, *rows]:
            print("  ".join(c.rjust(w) if i in (1, 2, 3) else c.ljust(w)
                            for i, (c, w) in enumerate(zip(row, widths))).rstrip())
        for e in refused:
            print(f"refused {_shown(e.path)}: {e.refused}")
        print(f"total: {len(clips)} clip(s), {frames} frames, {seconds / 60:.1f} min ({by_rate or 'none'}); "
              f"{len(refused)} refused")
    return 2 if refused else 0


def cmd_synth(args: argparse.Namespace) -> int:
    from data_tools.synth_settings import SYNTH_OPTIONS
    from tracker.app.api import synthesize

    check_output_folder(args.out, empty=not args.overwrite, replaceable=("cameras.json", "meta.json"))
    if (args.then or args.switch_at) and not (args.then and args.switch_at):
        raise InputError("a transition needs both --then FILE and --switch-at FRAME")
    synthesize(args.mocap, args.out, skeleton=args.skeleton, length_unit=args.length_unit, joint_map=args.joint_map,
               then=args.then, then_skeleton=args.then_skeleton, then_joint_map=args.then_joint_map,
               switch_at=args.switch_at, fade=args.fade, overwrite=args.overwrite, overwrite_flag="--overwrite",
               progress=lambda it: progress_bar(it, desc="rendering", unit="frame"),
               **{o.name: getattr(args, o.name) for o in SYNTH_OPTIONS})
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from tracker.app.api import show

    if not args.out and not args.video:
        raise InputError("nothing to write: give --out FILE.png and/or --video FILE.mp4")
    if args.out:
        check_output_file(args.out, "--out", (".png",), new=not args.overwrite)
    if args.video:
        check_output_file(args.video, "--video", (".mp4",), new=not args.overwrite)
    written = show(args.sequence, frame=args.frame, poses=args.poses, out=args.out, video=args.video,
                   progress=lambda it: progress_bar(it, desc="video", unit="frame"))
    for line in written:
        log.info(line)
    return 0


def _parse_views(text: str | None, n_views: int) -> list[int]:
    """``--views 0,2`` as camera indices, checked by :func:`tracker.app.tracking.check_views`."""
    from tracker.app.tracking import check_views

    if text is None:
        return list(range(n_views))
    try:
        views = [int(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise InputError(f"--views must be comma-separated camera indices, got {text!r}") from None
    return check_views(views, n_views)


def cmd_compare(args: argparse.Namespace) -> int:
    from tracker.app.compare import compare, finished_runs

    command = shlex.join([*invoked_as().split(), *args.argv])  # as typed, recorded in report.html
    try:
        summary = compare(args.experiment, args.out, jobs=args.jobs, backend=args.backend, address=args.address,
                          threads=args.threads, data_root=args.data_root, overwrite=args.overwrite,
                          videos=args.videos, progress=shows_progress(), command=command)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: every finished run is kept, and the same command continues
        close_bars()
        done, total = finished_runs(args.out)
        kept = f"{done} of {total} runs finished and kept" if total else "nothing run yet"
        log.warning(f"interrupted: {kept} in {args.out}; continue with: {command}")
        return interrupted_status()
    print(summary["table"])
    log.info(f"-> {Path(args.out) / 'table.md'}, table.csv, per_frame.png, report.html")
    return 0


def cmd_fetch(args: argparse.Namespace) -> int:
    from tracker.app.fetching import fetch

    trials = args.trials if args.dataset in (None, "cmu") else [args.dataset, *args.trials]  # `fetch 07_01`
    fetch(trials, experiment=args.experiment, data_root=args.data_root, mirror=args.mirror, timeout=args.timeout)
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from tracker.app.demo import run_demo

    return run_demo(Path(args.out), args.frames, overwrite=args.overwrite)


def _progress_bar(desc: str):
    """A ``progress(done, total, metrics)`` callback drawing one tqdm bar (created on the first call; none under
    ``--quiet``)."""
    state = {}

    def progress(done: int, total: int, metrics: dict) -> None:
        if "bar" not in state:
            state["bar"] = progress_bar(total=total, desc=desc, unit="it")
        bar = state["bar"]
        bar.update(done - bar.n)
        bar.set_postfix({k: f"{v:.4g}" for k, v in metrics.items()})
        if done >= total:
            bar.close()

    progress.close = lambda: state["bar"].close() if "bar" in state else None  # type: ignore[attr-defined]
    return progress


def cmd_train(args: argparse.Namespace) -> int:
    from tracker.app.train_file import TrainingStopped, train_into

    progress = _progress_bar(f"training {args.prior}")
    try:
        model = train_into(args.out, args.prior, args.mocap, skeletons=args.skeleton, fps=args.fps,
                           joint_maps=args.joint_map, seed=args.seed, progress=progress, resume=args.resume,
                           overwrite=args.overwrite, overwrite_flag="--overwrite",
                           **given_options(args, prior_entry(args.prior).train_options))
    except TrainingStopped as stop:  # Ctrl-C or SIGTERM: the training state at the stop (if any) stays for --resume
        progress.close()
        command = shlex.join([*invoked_as().split(), *args.argv])
        again = (f"continue with: {command}{'' if args.resume else ' --resume'}" if stop.resumable
                 else f"nothing saved; start again with: {command}")
        log.warning(f"interrupted: {again}")
        return interrupted_status()
    print(f"{model.summary()} -> {args.out}")  # how the training went: its result
    return 0


#: What the command line adds to the parsed arguments besides the run's: allowed beside ``--resume``.
_CONSOLE = ("quiet", "verbose", "argv")


def _views(text: str | None) -> list[int] | None:
    """``--views 0,2`` as camera indices (the run checks them against the sequence's cameras)."""
    if text is None:
        return None
    try:
        return [int(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise InputError(f"--views must be comma-separated camera indices, got {text!r}") from None


def _track_request(args: argparse.Namespace):
    """The run the parsed arguments ask for (:class:`tracker.app.run_folder.TrackRequest`)."""
    from tracker.app.run_folder import TrackRequest

    likelihood = likelihood_entry(args.likelihood or UNNAMED_LIKELIHOOD)
    settings = {name: getattr(args, name) for name in TRACK_SETTINGS if name != "views"}
    return TrackRequest.of(args.sequence, args.prior, models=args.model or (), likelihood=args.likelihood,
                           init=args.init, train_mocap=args.train_mocap, video=args.video, plugins=args.plugin,
                           views=_views(args.views), **settings,
                           **given_options(args, prior_entry(args.prior).options),
                           **given_options(args, likelihood.options))


def _resumed_request(args: argparse.Namespace):
    """The request kept in the folder of ``--resume`` (also one an earlier version kept: its parsed arguments)."""
    from tracker.app.run_folder import saved_request

    defaults = vars(build_parser(["track"]).parse_args(["track"]))
    given = [k for k, v in vars(args).items() if k not in ("resume", "command", "plugin", "threads", *_CONSOLE)
             and v not in (None, False, [], defaults.get(k))]
    if given:
        raise InputError(f"--resume takes no other arguments (got {', '.join('--' + g for g in given)})")
    return saved_request(args.resume, earlier=lambda saved: _track_request(argparse.Namespace(
        **{**defaults, **saved, "plugin": saved.get("plugin", [])})))


def cmd_track(args: argparse.Namespace) -> int:
    from tracker.app.run_folder import run_in_folder, TrackingStopped
    from tracker.app.tracking import metrics_line

    if args.resume:
        request, out = _resumed_request(args), Path(args.resume)
        if request is None:
            from tracker.app.run_folder import REQUEST_FILE

            raise InputError(f"no interrupted run to resume here (no {REQUEST_FILE})", args.resume)
    else:
        missing = [name for name, given in (("DIR", args.sequence), ("--prior", args.prior), ("--out", args.out))
                   if not given]
        if missing:
            raise InputError(f"track: missing {' and '.join(missing)} (usage: {PROG} track DIR --prior NAME --out "
                             f"OUTDIR, or {PROG} track --resume OUTDIR)")
        request, out = _track_request(args), Path(args.out)
    errors: list[float] = []  # the mpjpe_abs of each frame, for the bar
    bars: list = []  # the bar appears with the first tracked frame: a refusal before that stays one line
    frames: list[int] = []

    def on_frame(step, err: float | None) -> None:
        if not bars:  # counts the tracked frames; its rate starts with the second (the first has none)
            bars.append(progress_bar(total=frames[0], initial=1, desc=f"tracking ({request.prior})", unit="frame"))
        else:
            bars[0].update(1)
        if err is not None:
            errors.append(err)
            bars[0].set_postfix({"mpjpe_abs": f"{err:.0f} mm", "mean": f"{np.mean(errors):.0f} mm"})

    try:
        run = run_in_folder(request, out, overwrite=args.overwrite, resume=bool(args.resume), on_frame=on_frame,
                            on_start=frames.append, invocation={"argv": [PROG, *args.argv]},
                            overwrite_flag="--overwrite", resume_command=f"{PROG} track --resume {out}")
    except TrackingStopped as stop:  # Ctrl-C or SIGTERM
        for bar in bars:
            bar.close()
        if stop.partial is not None:
            kept = f" after {len(stop.partial.tracked_frames)} frame(s): partial result in {out}"
        elif stop.resumable:
            kept = f": saved arguments in {out}"
        else:
            log.warning("interrupted before the first frame was tracked; nothing was kept: run the same command "
                        "again")
            return interrupted_status()
        log.warning(f"interrupted{kept}; resume with: {PROG} track --resume {out}")
        return interrupted_status()
    for bar in bars:
        bar.update(frames[0] - bar.n)
        bar.close()
    if run.recovered_frames:
        log.warning(f"no particle explained frame(s) {run.recovered_frames}; the filter re-diffused around its last "
                    "estimate")
    layers = run.settings["annealing_layers"]
    log.info(f"{run.settings['particles']} particles{f' x {layers} annealing layers' if layers > 1 else ''}, "
             f"{len(run.settings['views'])} view(s): {run.seconds_per_frame:.3f} s per frame")
    n = len(run.tracked_frames)
    print(f"{request.prior}, {n} frame{'' if n == 1 else 's'} tracked: {metrics_line(run.to_dict()['metrics'])} "
          f"-> {out}")
    return 0


COMMANDS = {"convert": cmd_convert, "synth": cmd_synth, "show": cmd_show, "train": cmd_train, "track": cmd_track,
            "compare": cmd_compare, "demo": cmd_demo, "fetch": cmd_fetch, "corpus": cmd_corpus}
COMMANDS.update(VIDEO_COMMANDS)


def _plugins_from_argv(argv: list[str]) -> list[str]:
    """``--plugin`` values, read before the parser is built (plugins add choices and flags to it)."""
    found = []
    for i, a in enumerate(argv):
        if a == "--plugin" and i + 1 < len(argv):
            found.append(argv[i + 1])
        elif a.startswith("--plugin="):
            found.append(a.split("=", 1)[1])
    return found


def run() -> NoReturn:
    """The ``pose-tracker`` program: :func:`main` on the command line's arguments, then exit with its status.

    The objects left at exit are frozen first (:func:`gc.freeze`), so that the interpreter's final collections
    skip them: numba's compiled-code objects made every exit take 0.15-0.25 s longer."""
    status = main()
    gc.freeze()
    sys.exit(status)


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command line (``argv``, default the process's arguments); returns the exit status. SIGTERM stops
    a command as Ctrl-C does (:func:`tracker.app.console.stop_signals`; exit status 143)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    configure_logging()  # INFO until the arguments say otherwise (a deprecated flag warns while they are parsed)
    with stop_signals():
        try:
            for spec in _plugins_from_argv(argv):
                import_plugin(spec)
            args = parse_arguments(argv)
            configure_logging(verbosity(args.quiet, args.verbose))
            args.argv = argv
            log.debug(f"arguments: {vars(args)}")
            if args.command != "compare":  # compare gives each worker its share instead
                set_threads(args.threads)
            return COMMANDS[args.command](args)
        except InputError as exc:
            close_bars()  # the error is the last line: no bar drawn again below it
            print(error_line(str(exc)), file=sys.stderr)
            return 2
        except KeyboardInterrupt:  # Ctrl-C where a command has nothing to keep (those that do answer it themselves)
            close_bars()
            log.warning("interrupted; nothing was written that a rerun would not write again")
            return interrupted_status()
        except (MemoryError, RuntimeError) as exc:  # sizes within the checked ranges that this machine cannot hold
            if isinstance(exc, RuntimeError) and "can't allocate memory" not in str(exc):  # torch's allocator says so
                raise
            close_bars()
            reason = str(exc).splitlines()[0][:160] if str(exc) else "allocation failed"
            print(error_line(f"not enough memory for these settings ({reason}); choose smaller sizes"),
                  file=sys.stderr)
            return 2
