"""``pose-tracker train``: train a learned motion prior on mocap clips."""
from __future__ import annotations

import argparse
import logging
import shlex
from typing import Sequence

from tracker.app.commands.arguments import (catalogue, check_clashes, chosen, fps_type, given_options, plugin_group,
                                            seed_type, wrapped)
from tracker.app.console import interrupted_status, invoked_as, progress_bar
from tracker.app.plugins import available_priors, prior_entry

log = logging.getLogger(__name__)

NAME = "train"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    r = sub.add_parser("train", parents=parents, help="train a learned motion prior on mocap clips",
                       description="Retarget the clips (any subjects, each with its own skeleton) to the 15-cone "
                                   "model at --fps, convert them to the invariant representation and train the "
                                   "prior; the model file keeps its normalisation statistics and the data settings "
                                   "it was trained with.")
    trainable = [n for n in available_priors() if prior_entry(n).train is not None]
    r.formatter_class = argparse.RawDescriptionHelpFormatter
    r.usage = "%(prog)s --prior NAME --mocap PATH [PATH ...] --out MODEL [options]"
    r.description = wrapped(r.description)
    if chosen(argv, "--prior") not in trainable:
        r.description += "\n\n" + catalogue("learned priors", trainable, "train")
    r.add_argument("--prior", required=True, choices=trainable, metavar="NAME", help="which prior to train")
    r.add_argument("--mocap", required=True, nargs="+", metavar="PATH",
                   help="training clips: mocap files (.amc or .bvh), folders (every mocap file in them, "
                        "recursively) or glob patterns ('bandai2/*walk*.bvh'), in sorted order; converted clips "
                        "are cached ($POSE_TRACKER_CACHE)")
    r.add_argument("--skeleton", nargs="+", metavar="ASF",
                   help="ASF skeleton(s): one for all .amc clips or one per clip (default: <subject>.asf beside each)")
    r.add_argument("--fps", type=fps_type, default=60.0,
                   help="frame rate of the model (default 60, synth's); every clip is resampled to it")
    r.add_argument("--joint-map", nargs="+", metavar="FILE",
                   help="joint map(s): one for all clips or one per clip, 'none' for a clip whose joint names are "
                        "recognised (see convert --help)")
    r.add_argument("--seed", type=seed_type, default=0, help="random seed (default 0)")
    r.add_argument("--resume", action="store_true",
                   help="continue an interrupted training from OUT.checkpoint (same arguments as before); "
                        "a training stopped before its first checkpoint starts from the beginning")
    r.add_argument("--out", required=True, help="output model file (.pt)")
    r.add_argument("--overwrite", action="store_true", help="replace an existing model file")
    check_clashes(r, {f"prior {n}": prior_entry(n).train_options for n in trainable})
    named = chosen(argv, "--prior")
    if named in trainable:
        plugin_group(r, f"training options of the {named} prior", prior_entry(named).train_options)
    return r


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


def run(args: argparse.Namespace) -> int:
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
