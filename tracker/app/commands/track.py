"""``pose-tracker track``: track a person through a sequence with a particle filter."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import Sequence

import numpy as np

from tracker.app.commands.arguments import (UNNAMED_LIKELIHOOD, catalogue, check_clashes, chosen, given_options,
                                            plugin_group, wrapped)
from tracker.app.console import PROG, interrupted_status, progress_bar
from tracker.app.plugins import available_likelihoods, available_priors, likelihood_entry, prior_entry
from tracker.app.schema import TRACK_SETTINGS, add_flags
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

NAME = "track"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    t = sub.add_parser("track", parents=parents, help="track a person through a sequence with a particle filter",
                       description="Track a sequence (a pose-tracker sequence folder or PARSEC bodytrack's) with an "
                                   "SIR particle filter "
                                   "and an image likelihood; writes OUTDIR/result.json and OUTDIR/estimates.npz.")
    t.add_argument("sequence", metavar="DIR", nargs="?", help="sequence folder")
    t.add_argument("--prior", choices=available_priors(), metavar="NAME",
                   help=f"motion prior (required; {PROG} track --help lists them)")
    t.add_argument("--model", nargs="+", metavar="MODEL",
                   help="a learned prior's model file(s) (a CRBM takes several: orders that grow the history, or an "
                        "ensemble of one order)")
    t.add_argument("--likelihood", default=None, choices=available_likelihoods(), metavar="NAME",
                   help="image likelihood (default keypoints+edge-silhouette for a sequence with 2-D keypoints, "
                        "else edge-silhouette)")
    add_flags(t, ("particles", "views", "frames", "seed", "annealing_layers", "resampling"))
    t.add_argument("--init", help="POSES.npz whose 'poses' are the known first frames (default: ground truth, or "
                                  "the bodytrack InitialPose.txt)")
    add_flags(t, ("known_frames",))
    t.add_argument("--train-mocap", nargs="+", default=None, metavar="FILE",
                   help="mocap clips whose frame-to-frame changes set the random-walk scale (default: the shipped "
                        "subject-7 walks 07_01 and 07_02); bodytrack folders use PoseParameters.txt")
    add_flags(t, ("device", "ess_threshold", "survival_rate", "layer_diffusion_decay"))
    t.add_argument("--out", help="output folder (required)")
    t.add_argument("--video", help="also write an overlay video of the estimates (.mp4)")
    t.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty output folder, replacing the results there")
    add_flags(t, ("checkpoint_every",))
    t.add_argument("--resume", metavar="OUTDIR",
                   help="continue an interrupted run from OUTDIR/checkpoint.npz with its original settings "
                        "(give no other arguments); a run stopped before its first checkpoint starts from its "
                        "first frame")
    priors = {f"prior {n}": prior_entry(n).options for n in available_priors()}
    likelihoods = {f"likelihood {n}": likelihood_entry(n).options for n in available_likelihoods()}
    shared = ({o.name for opts in priors.values() for o in opts}
              & {o.name for opts in likelihoods.values() for o in opts})
    if shared:
        raise InputError(f"a prior and a likelihood both declare the option(s) {', '.join(sorted(shared))}; "
                         "rename one of them")
    check_clashes(t, {**priors, **likelihoods})
    t.formatter_class = argparse.RawDescriptionHelpFormatter
    t.usage = "%(prog)s DIR --prior NAME [--model MODEL ...] --out OUTDIR [options]\n       %(prog)s --resume OUTDIR"
    prior = chosen(argv, "--prior")
    t.description = wrapped(t.description)
    if prior not in available_priors():  # the catalogue; a named prior's help names no other prior
        t.description += ("\n\n" + catalogue("priors", available_priors(), "track") + "\n\n"
                          + catalogue("likelihoods", available_likelihoods(), "track", "--likelihood"))
    else:
        plugin_group(t, f"options of the {prior} prior", prior_entry(prior).options)
    likelihood = chosen(argv, "--likelihood") or UNNAMED_LIKELIHOOD
    if likelihood in available_likelihoods():
        plugin_group(t, f"options of the {likelihood} likelihood", likelihood_entry(likelihood).options)
    return t


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
    """The request kept in the folder of ``--resume``; ``--resume`` takes no other arguments."""
    from tracker.app.run_folder import saved_request

    program = argparse.ArgumentParser()
    add_parser(program.add_subparsers(dest="command"), [], ["track"])
    defaults = vars(program.parse_args(["track"]))
    given = [k for k, v in vars(args).items() if k not in ("resume", "command", "plugin", "threads", *_CONSOLE)
             and v not in (None, False, [], defaults.get(k))]
    if given:
        raise InputError(f"--resume takes no other arguments (got {', '.join('--' + g for g in given)})")
    return saved_request(args.resume)


def run(args: argparse.Namespace) -> int:
    from tracker.app.run_folder import TrackingStopped, run_in_folder
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
