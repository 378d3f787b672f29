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

from data_tools.files import (atomic_path, check_not_inside, check_output_file, check_output_folder, first_missing,
                              undone_unless_started)
from tracker.app.console import (PROG, close_bars, configure_logging, error_line, interrupted_status, invoked_as,
                                 progress_bar, shows_progress, stop_signals, verbosity)
from tracker.app.parser import UNNAMED_LIKELIHOOD, build_parser, given_options, parse_arguments
from tracker.app.plugins import import_plugin, likelihood_entry, prior_entry
from tracker.app.schema import TRACK_SETTINGS
from tracker.app.threads import set_threads
from tracker.app.video_commands import COMMANDS as VIDEO_COMMANDS
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

def _convert_one(mocap: str | Path, skeleton, fps: float | None, length_unit, out: Path, joint_map=None):
    from data_tools.clip_io import save_converted_clip
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from tracker.app.plugins import load_plugins

    load_plugins()  # the mocap readers of installed plugins (entry points) register on import
    clip = load_mocap(mocap, skeleton, length_unit, joint_map=joint_map)
    result = retarget(clip, fps=fps)
    with atomic_path(out) as tmp:
        save_converted_clip(result, tmp)
    return clip, result


#: A mean retarget residual (mm) above which a conversion is suspect: a well-read file fits within a few mm.
RESIDUAL_WARNING_MM = 10.0


def _check_residual(name: str, residual_mm: float) -> None:
    """Warn when a clip's mean retarget residual points to a wrong length unit or joint mapping."""
    if residual_mm > RESIDUAL_WARNING_MM:
        log.warning(f"{name}: mean retarget residual {residual_mm:.1f} mm; a well-read file fits within a few mm, "
                    "and tens of mm point to a wrong length unit (--length-unit) or joint mapping (--joint-map): "
                    "see docs/guide/motion_capture.md")


def cmd_convert(args: argparse.Namespace) -> int:
    out = check_output_file(args.out, "the output", (".npz",), new=not args.overwrite)
    check_not_inside(out, {"mocap file": args.mocap, **({"skeleton": args.skeleton} if args.skeleton else {})})
    clip, result = _convert_one(args.mocap, args.skeleton, args.fps, args.length_unit, out, args.joint_map)
    for note in clip.notes:
        log.info(f"note: {Path(args.mocap).name}: {note}")
    print(f"{Path(args.mocap).name}: {clip.summary()}; {len(result.poses)} frames at {result.fps:g} fps, "
          f"mean retarget residual {result.mean_residual:.2f} mm -> {out}")  # the residual: how well it went
    _check_residual(Path(args.mocap).name, result.mean_residual)
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
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from data_tools.synth import SynthConfig, synthesize
    from tracker.app.plugins import load_plugins

    load_plugins()  # the mocap readers of installed plugins (entry points) register on import
    check_output_folder(args.out, empty=not args.overwrite, replaceable=("cameras.json", "meta.json"))
    settings = SynthConfig(views=args.cameras, fps=args.fps, start=args.start, frames=args.frames, seed=args.seed,
                           width=args.width, height=args.height, noise=args.noise,
                           lighting_change=args.lighting_change, occluder=args.occluder,
                           missing_camera=args.missing_camera, turn=args.turn)
    clip = load_mocap(args.mocap, args.skeleton, args.length_unit, joint_map=args.joint_map)
    for note in clip.notes:
        log.info(f"note: {Path(args.mocap).name}: {note}")
    result = retarget(clip, fps=args.fps)
    _check_residual(Path(args.mocap).name, result.mean_residual)
    if args.then or args.switch_at:
        from data_tools.transition import cross_fade

        if not (args.then and args.switch_at):
            raise InputError("a transition needs both --then FILE and --switch-at FRAME")
        second = retarget(load_mocap(args.then, args.then_skeleton, args.length_unit, joint_map=args.then_joint_map),
                          fps=args.fps)
        result, change = cross_fade(result, second, args.switch_at, args.fade)
        log.info(f"transition: {Path(args.mocap).name} until frame {change.fade_start}, cross-faded into "
                 f"{Path(args.then).name} (from its frame {change.second_start}) by frame {change.switch}")
    out = synthesize(result, args.out, settings, source=result.source if args.then else str(args.mocap),
                     overwrite=args.overwrite,
                     progress=lambda it: progress_bar(it, desc="rendering", unit="frame"))
    log.info(f"{Path(args.mocap).name}: {out.n_frames} frames x {args.cameras} cameras at "
             f"{result.fps:g} fps -> {out.root} ({out.render_seconds / out.n_frames * 1000:.0f} ms per frame "
             f"to render and write)")
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


def _progress_bar(desc: str, on_start=None):
    """A ``progress(done, total, metrics)`` callback drawing one tqdm bar (created on the first call; none under
    ``--quiet``); ``on_start()`` runs at the first call, when the work has passed every check and begun."""
    state = {}

    def progress(done: int, total: int, metrics: dict) -> None:
        if "bar" not in state:
            if on_start is not None:
                on_start()
            state["bar"] = progress_bar(total=total, desc=desc, unit="it")
        bar = state["bar"]
        bar.update(done - bar.n)
        bar.set_postfix({k: f"{v:.4g}" for k, v in metrics.items()})
        if done >= total:
            bar.close()

    progress.close = lambda: state["bar"].close() if "bar" in state else None  # type: ignore[attr-defined]
    return progress


def train(*args, **kwargs):
    """:func:`tracker.app.api.train`, the API imported on the first call (help texts do without it)."""
    from tracker.app.api import train as train_prior

    return train_prior(*args, **kwargs)


def track(*args, **kwargs):
    """:func:`tracker.app.api.track`, the API imported on the first call (help texts do without it)."""
    from tracker.app.api import track as track_sequence

    return track_sequence(*args, **kwargs)


def cmd_train(args: argparse.Namespace) -> int:
    out = check_output_file(args.out, "the model file", new=not args.overwrite)
    check_not_inside(out, {f"training file {i + 1}": f for i, f in enumerate([*args.mocap, *(args.skeleton or [])])})
    from data_tools.corpus import is_label_source, label_source
    from data_tools.load import load_training_clips

    options = given_options(args, prior_entry(args.prior).train_options)
    if is_label_source(options.get("labels")):  # a labels pattern or file is checked before any clip is read
        label_source(options["labels"]).training_keys()
    clips = load_training_clips(args.mocap, args.skeleton, args.fps, args.joint_map)  # every file read, checked first
    checkpoint = out.with_name(out.name + ".checkpoint")
    resume = args.resume and (checkpoint.exists() or not prior_entry(args.prior).resumable)  # the latter refused
    if args.resume and not resume:  # stopped before its first checkpoint: the whole training again
        log.info(f"no training checkpoint at {checkpoint}: training from the start")
    side = checkpoint.with_name(checkpoint.name + ".inputs.json")
    with undone_unless_started(first_missing(out), checkpoint, side) as work:  # refused: nothing stays behind

        def started() -> None:  # once every setting is checked
            work["started"] = True
            log.info(f"training a {args.prior} prior on {len(clips)} clip(s), "
                     f"{sum(len(c.poses) for c in clips)} frames at {clips[0].fps:g} fps")

        progress = _progress_bar(f"training {args.prior}", on_start=started)
        try:
            model = train(args.prior, clips, skeletons=args.skeleton, fps=clips[0].fps, seed=args.seed,
                          progress=progress, checkpoint=checkpoint, resume=resume, **options)
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the training state at the stop (if any) stays for --resume
            progress.close()
            work["started"] = True  # the model file is written only at the end: nothing else to undo
            command = shlex.join([*invoked_as().split(), *args.argv])
            if not checkpoint.exists():  # stopped before the training kept any state, or a prior that cannot resume
                side.unlink(missing_ok=True)
                again = f"nothing saved; start again with: {command}"
            else:
                again = f"continue with: {command}{'' if args.resume else ' --resume'}"
            log.warning(f"interrupted: {again}")
            return interrupted_status()
    with atomic_path(out) as tmp:
        model.save(tmp)
    print(f"{model.summary()} -> {out}")  # how the training went: its result
    return 0


TRACK_ARGS = "track_arguments.json"
#: What the command line adds to the parsed arguments besides the run's settings: not saved for --resume, and
#: allowed beside it.
_CONSOLE = ("quiet", "verbose", "argv")


def _saved_arguments(args: argparse.Namespace) -> dict:
    """The arguments of a run as kept in ``OUTDIR/track_arguments.json`` (paths already made absolute)."""
    saved = {k: v for k, v in vars(args).items() if k not in ("resume", "command", "threads", *_CONSOLE)}
    saved["plugin"] = [str(Path(p).resolve()) if p.endswith(".py") else p for p in args.plugin]
    return saved


def _same_run(saved: dict, given: dict) -> list[str]:
    """The arguments in which ``given`` differs from an unfinished run's ``saved`` ones (``--overwrite`` aside)."""
    def plain(d: dict) -> dict:
        return json.loads(json.dumps({k: v for k, v in d.items() if k != "overwrite"}))

    a, b = plain(saved), plain(given)
    return sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))


def _track_arguments(args: argparse.Namespace) -> argparse.Namespace:
    """The arguments of a run: as given (paths made absolute, kept in OUTDIR for --resume), or with --resume
    those saved by the interrupted run. The same command again, into the folder of its unfinished run, continues
    that run as ``--resume OUTDIR`` does."""
    if args.resume:
        defaults = vars(build_parser(["track"]).parse_args(["track"]))
        given = [k for k, v in vars(args).items() if k not in ("resume", "command", "plugin", "threads", *_CONSOLE)
                 and v not in (None, False, [], defaults.get(k))]
        if given:
            raise InputError(f"--resume takes no other arguments (got {', '.join('--' + g for g in given)})")
        path = Path(args.resume) / TRACK_ARGS
        if not path.is_file():
            raise InputError(f"no interrupted run to resume here (no {TRACK_ARGS})", args.resume)
        from data_tools.textfiles import read_json

        saved = read_json(path, "saved track arguments")
        if not isinstance(saved, dict):
            raise InputError("saved track arguments are not a JSON object", path)
        for spec in saved.get("plugin", []):
            import_plugin(spec)
        return argparse.Namespace(**{**vars(args), **saved, "resume": args.resume})
    missing = [name for name, given in (("DIR", args.sequence), ("--prior", args.prior), ("--out", args.out))
               if not given]
    if missing:
        raise InputError(f"track: missing {' and '.join(missing)} (usage: {PROG} track DIR --prior NAME --out OUTDIR, "
                         f"or {PROG} track --resume OUTDIR)")
    for key in ("sequence", "out", "video", "init"):
        if getattr(args, key):
            setattr(args, key, str(Path(getattr(args, key)).resolve()))
    for key in ("model", "train_mocap"):
        if getattr(args, key):
            setattr(args, key, [str(Path(m).resolve()) for m in getattr(args, key)])
    if isinstance(getattr(args, "components", None), str):  # a mixture's components name their own model files
        from tracker.engine.components import with_model_paths

        args.components = with_model_paths(args.components, f"prior {args.prior}",
                                           lambda m: str(Path(m).expanduser().resolve()))
    unfinished = Path(args.out) / TRACK_ARGS
    if unfinished.is_file() and not args.overwrite:
        from data_tools.textfiles import read_json

        saved = read_json(unfinished, "saved track arguments")
        differ = _same_run(saved, _saved_arguments(args)) if isinstance(saved, dict) else ["all"]
        if differ:
            raise InputError(f"the output folder holds an unfinished run of other arguments ({', '.join(differ)}): "
                             f"continue it with {PROG} track --resume {args.out}, or pass --overwrite to start this "
                             "one in its place", args.out)
        log.info(f"{args.out} holds this run, unfinished: continuing it")
        args.resume = args.out
    return args


def cmd_track(args: argparse.Namespace) -> int:
    from data_tools.estimates import read_poses_file
    from data_tools.files import write_text_atomic
    from tracker.app.api import default_likelihood, load_sequence
    from tracker.app.tracking import TrackingInterrupted, check_frames, metrics_line
    from tracker.app.visualize import overlay_frames, write_video

    args = _track_arguments(args)
    # before any tracking, so a bad output path loses no work; --resume continues in its own folder
    out = check_output_folder(args.out, empty=not (args.overwrite or args.resume))
    check_not_inside(out, {"sequence folder": args.sequence})
    if args.video:
        check_output_file(args.video, "--video", (".mp4",), new=not (args.overwrite or args.resume))
        check_not_inside(args.video, {"sequence folder": args.sequence})
    checkpoint = out / "checkpoint.npz"
    errors: list[float] = []  # the mpjpe_abs of each frame, for the bar
    bars: list = []  # the bar appears with the first tracked frame: a refusal before that stays one line
    try:
        with undone_unless_started(first_missing(out)) as work:  # refused or stopped before the first frame:
            # nothing stays behind
            seq = load_sequence(args.sequence)
            likelihood = args.likelihood or default_likelihood(seq)
            likelihood_options = given_options(args, likelihood_entry(likelihood).options)
            foreign = sorted(set(given_options(args, likelihood_entry(UNNAMED_LIKELIHOOD).options))
                             - set(likelihood_options))
            if foreign:
                raise InputError(f"--{foreign[0].replace('_', '-')} does not apply to the {likelihood} likelihood, "
                                 "which this sequence takes (it has no keypoints)", args.sequence)
            views = _parse_views(args.views, seq.n_views)
            init = read_poses_file(args.init, "initial poses", seq.model) if args.init else None
            T, _, n_known = check_frames(seq, args.frames, args.known_frames, init)
            if not args.resume:
                checkpoint.unlink(missing_ok=True)  # an earlier run's, in a folder given with --overwrite
                write_text_atomic(out / TRACK_ARGS, json.dumps(_saved_arguments(args), indent=1))
            elif not checkpoint.exists():  # stopped before its first checkpoint (or killed): the whole run again
                log.info(f"no checkpoint in {out}: tracking from the first frame with the saved arguments")

            def on_frame(step, err: float | None) -> None:
                work["started"] = True
                if not bars:  # counts the tracked frames; its rate starts with the second (the first has none)
                    bars.append(progress_bar(total=T - n_known, initial=1, desc=f"tracking ({args.prior})",
                                             unit="frame"))
                else:
                    bars[0].update(1)
                if err is not None:
                    errors.append(err)
                    bars[0].set_postfix({"mpjpe_abs": f"{err:.0f} mm", "mean": f"{np.mean(errors):.0f} mm"})

            try:
                run = track(seq, args.prior, models=args.model or (), likelihood=likelihood,
                            **given_options(args, prior_entry(args.prior).options), **likelihood_options,
                            **{name: getattr(args, name) for name in TRACK_SETTINGS if name != "views"},
                            views=views, init=init, train_mocap=args.train_mocap, on_frame=on_frame,
                            checkpoint=checkpoint, resume=bool(args.resume) and checkpoint.exists())
            except TrackingInterrupted as stop:  # Ctrl-C or SIGTERM once the filter runs
                for bar in bars:
                    bar.close()
                if stop.partial is None and not args.resume:  # before its first frame: as if never started
                    work["started"] = False
                    raise KeyboardInterrupt from None
                work["started"] = True
                if stop.partial is not None:
                    stop.partial.invocation = {"argv": [PROG, *args.argv]}
                    stop.partial.save(out, overwrite=True)
                done = "" if stop.partial is None else f" after {len(stop.partial.tracked_frames)} frame(s)"
                kept = "partial result" if stop.partial is not None else "saved arguments"
                log.warning(f"interrupted{done}: {kept} in {out}; resume with: {PROG} track --resume {out}")
                return interrupted_status()
    except KeyboardInterrupt:  # before the first frame: nothing kept but the saved arguments of a resumed run
        again = (f"resume with: {PROG} track --resume {out}" if args.resume
                 else f"nothing was kept: run the same command again")
        log.warning(f"interrupted before the first frame was tracked; {again}")
        return interrupted_status()
    for bar in bars:
        bar.update(T - n_known - bar.n)
        bar.close()
    run.invocation = {"argv": [PROG, *args.argv]}
    result = run.save(out, overwrite=True)
    (out / TRACK_ARGS).unlink(missing_ok=True)
    if run.recovered_frames:
        log.warning(f"no particle explained frame(s) {result['recovered_frames']}; the filter re-diffused around "
                    "its last estimate")
    layers = run.settings["annealing_layers"]
    log.info(f"{args.particles} particles{f' x {layers} annealing layers' if layers > 1 else ''}, {len(views)} "
             f"view(s): {run.seconds_per_frame:.3f} s per frame")
    n = result["frames_tracked"]
    print(f"{args.prior}, {n} frame{'' if n == 1 else 's'} tracked: {metrics_line(result['metrics'])} -> {out}")
    if args.video:
        write_video(Path(args.video), overlay_frames(seq, run.poses, views, run.errors, run.first_tracked,
                                                     estimate_name=args.prior), seq.fps or 25.0)
        log.info(f"overlay video -> {args.video}")
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
