"""Command line: ``python -m tracker <command>`` (the contract: DESIGN.md "Command line", README).

The command line only parses arguments and calls the public API
(:mod:`tracker.app.api`); the choices of ``--prior`` and ``--likelihood`` and
each plugin's own flags come from the registries. Every bad input ends with a
one-line reason on stderr and exit status 2.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from data_tools.checks import MAX_FPS, MAX_IMAGE_SIDE, MAX_MM_PER_UNIT, MAX_VIEWS, MIN_FPS, MIN_MM_PER_UNIT
from data_tools.files import atomic_path, check_output_file, check_output_folder
from tracker.app.api import (
    TRACK_ANNEALING_LAYERS, available_likelihoods, available_priors, build_likelihood, build_prior,
    likelihood_entry, load_sequence, prior_entry, track, train,
)
from tracker.app.plugins import import_plugin
from tracker.app.threads import set_threads
from tracker.engine.resampling import SCHEMES
from tracker.core.errors import InputError
from tracker.engine.registry import Option


def _number(kind: type, minimum: float, strict: bool, maximum: float | None = None, strict_max: bool = False):
    """An argparse type: ``kind`` (int or float), finite, above (``strict``) or at least ``minimum``, and below
    (``strict_max``) or at most ``maximum`` when given; the message gives the range."""
    noun = "an integer" if kind is int else "a number"
    bound = f"greater than {minimum:g}" if strict else f"at least {minimum:g}"
    if maximum is not None:
        bound += f" and {'less than' if strict_max else 'at most'} {maximum if kind is int else format(maximum, 'g')}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None
        if (kind is float and not np.isfinite(value)) or value < minimum or (strict and value == minimum) \
                or (maximum is not None and (value > maximum or (strict_max and value == maximum))):
            raise argparse.ArgumentTypeError(f"must be {bound}, got {text}")
        return value

    return parse


_positive_float = _number(float, 0.0, strict=True)
_non_negative_float = _number(float, 0.0, strict=False)
_positive_int = _number(int, 1, strict=False)
_non_negative_int = _number(int, 0, strict=False)
#: Plausible ranges of the command-line values that size arrays or scale arithmetic (the API checks its own).
_seed = _number(int, 0, strict=False, maximum=2 ** 63 - 1)
_fps = _number(float, MIN_FPS, strict=False, maximum=MAX_FPS)
_length_unit = _number(float, MIN_MM_PER_UNIT, strict=False, maximum=MAX_MM_PER_UNIT)
_image_side = _number(int, 1, strict=False, maximum=MAX_IMAGE_SIDE)
_views = _number(int, 1, strict=False, maximum=MAX_VIEWS)
#: Particles and annealing layers: far beyond any run (Taylor 2009 uses 200-1000 particles; Deutscher & Reid
#: 10 layers), and a million particles already take gigabytes per frame.
_particles = _number(int, 1, strict=False, maximum=1_000_000)
_layers = _number(int, 1, strict=False, maximum=100)


class _Parser(argparse.ArgumentParser):
    """argparse with exit status 2 and a one-line message for usage errors."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m tracker",
                description="3D human pose tracking with learned dynamical priors.")
    p.add_argument("--plugin", action="append", default=[], metavar="MODULE_OR_FILE",
                   help="import a module (or .py file) that registers priors or likelihoods; repeatable")
    p.add_argument("--threads", type=_positive_int, default=None,
                   help="threads for numpy/BLAS, OpenCV and torch (default: the cores available to the process)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    plugin_flag = argparse.ArgumentParser(add_help=False)  # --plugin is read before parsing; accepted anywhere
    plugin_flag.add_argument("--plugin", action="append", default=argparse.SUPPRESS, metavar="MODULE_OR_FILE",
                             help=argparse.SUPPRESS)
    sub.required = True

    c = sub.add_parser("convert", parents=[plugin_flag], help="convert a mocap clip (AMC+ASF or BVH) to body-model poses and markers",
                       description="Retarget a mocap clip to the 15-cone body model and write CLIP.npz with "
                                   "poses, markers (ground truth), model_markers, fps and the body shape.")
    c.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    c.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    c.add_argument("--fps", type=_fps, default=60.0, help="output frame rate in Hz (default 60)")
    c.add_argument("--length-unit", type=_length_unit, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred from the skeleton's height)")
    c.add_argument("--out", required=True, help="output .npz")

    s = sub.add_parser("synth", parents=[plugin_flag], help="render a mocap clip into a synthetic multi-view sequence",
                       description="Retarget a mocap clip, render it into a calibrated rig over a cluttered room "
                                   "and write the sequence folder (cameras.json, images/, background/, "
                                   "groundtruth.npz, meta.json).")
    s.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    s.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    s.add_argument("--out", required=True, help="output sequence folder")
    s.add_argument("--views", type=_views, default=4, help="number of cameras (default 4)")
    s.add_argument("--fps", type=_fps, default=60.0, help="frame rate in Hz (default 60)")
    s.add_argument("--start", type=_non_negative_int, default=0, help="first frame, at the output rate (default 0)")
    s.add_argument("--frames", type=_positive_int, default=None, help="number of frames (default: to the end)")
    s.add_argument("--seed", type=_seed, default=0,
                   help="random seed: scene, clothing, widths, noise (default 0)")
    s.add_argument("--width", type=_image_side, default=640, help="image width in pixels (default 640)")
    s.add_argument("--height", type=_image_side, default=480, help="image height in pixels (default 480)")
    s.add_argument("--noise", type=_number(float, 0.0, strict=False, maximum=255.0), default=2.0,
                   help="sensor noise std in grey levels of 255 (default 2)")
    s.add_argument("--lighting-change", type=_number(float, -0.9, strict=True, maximum=2.0, strict_max=True),
                   default=0.0, metavar="FRACTION",
                   help="brightness drifts from 1 to 1+FRACTION over the sequence (default 0)")
    s.add_argument("--occluder", action="store_true", help="put a pillar between camera 0 and the person")
    s.add_argument("--missing-camera", type=_non_negative_int, default=None, metavar="INDEX",
                   help="this camera delivers only black frames")
    s.add_argument("--turn", type=_number(float, -360.0, strict=False, maximum=360.0), default=0.0,
                   metavar="DEGREES", help="turn the whole clip about the vertical axis, so the person moves in "
                                           "another direction through the rig (default 0)")
    s.add_argument("--length-unit", type=_length_unit, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred)")
    s.add_argument("--overwrite", action="store_true", help="replace a non-empty output folder")
    s.add_argument("--then", metavar="FILE", help="a second clip the person changes to (e.g. a run after a walk): "
                                                 "cross-faded into at --switch-at")
    s.add_argument("--then-skeleton", metavar="ASF", help="ASF skeleton of --then (default: <subject>.asf beside it)")
    s.add_argument("--switch-at", type=_positive_int, default=None, metavar="FRAME",
                   help="with --then: the frame (output rate, before --start) where the second clip has taken over")
    s.add_argument("--fade", type=_positive_int, default=12, metavar="FRAMES",
                   help="with --then: frames of the cross-fade before --switch-at (default 12)")

    w = sub.add_parser("show", parents=[plugin_flag], help="draw the projected body model over every view of a sequence frame",
                       description="Draw the projected cones (ground truth, the initial pose, or --poses) over "
                                   "every camera view in one grid image, or a whole sequence as a video.")
    w.add_argument("sequence", metavar="DIR", help="sequence folder (own layout or PARSEC bodytrack)")
    w.add_argument("--frame", type=_non_negative_int, default=0, help="frame to draw (default 0)")
    w.add_argument("--poses", help="estimates.npz (poses T x D) to draw instead of the ground truth")
    w.add_argument("--out", help="output image (.png)")
    w.add_argument("--video", help="also write every frame to this video (.mp4)")

    r = sub.add_parser("train", parents=[plugin_flag], help="train a learned motion prior on mocap clips",
                       description="Retarget the clips (any subjects, each with its own skeleton) to the 15-cone "
                                   "model at --fps, convert them to the invariant representation and train the "
                                   "prior; the model file keeps its normalisation statistics and the data settings "
                                   "it was trained with.")
    trainable = [n for n in available_priors() if prior_entry(n).train is not None]
    r.add_argument("--prior", required=True, choices=trainable, help="which prior to train")
    r.add_argument("--mocap", required=True, nargs="+", metavar="FILE", help="training clips (.amc or .bvh)")
    r.add_argument("--skeleton", nargs="+", metavar="ASF",
                   help="ASF skeleton(s): one for all .amc clips or one per clip (default: <subject>.asf beside each)")
    r.add_argument("--fps", type=_fps, default=60.0, help="frame rate of the training data (default 60)")
    r.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    r.add_argument("--resume", action="store_true",
                   help="continue an interrupted training from OUT.checkpoint (same arguments as before)")
    r.add_argument("--out", required=True, help="output model file (.pt)")
    _add_plugin_options(r, {n: prior_entry(n).train_options for n in trainable})

    t = sub.add_parser("track", parents=[plugin_flag], help="track a person through a sequence with a particle filter",
                       description="Track a sequence (our layout or PARSEC bodytrack) with an SIR particle filter "
                                   "and an image likelihood; writes OUTDIR/result.json and OUTDIR/estimates.npz.")
    t.add_argument("sequence", metavar="DIR", nargs="?", help="sequence folder")
    t.add_argument("--prior", choices=available_priors(), help="motion prior (required)")
    t.add_argument("--model", nargs="+", metavar="MODEL",
                   help="trained prior model(s); for crbm several orders (e.g. 1 and 3) grow the history")
    t.add_argument("--likelihood", default="edge-silhouette", choices=available_likelihoods(),
                   help="image likelihood (default edge-silhouette)")
    t.add_argument("--particles", type=_particles, default=1000, help="number of particles (default 1000)")
    t.add_argument("--views", default=None, help="comma-separated camera indices (default: all)")
    t.add_argument("--frames", type=_positive_int, default=None,
                   help="track frames 0..N-1 (default: the whole sequence)")
    t.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    t.add_argument("--annealing-layers", type=_layers, default=TRACK_ANNEALING_LAYERS,
                   help=f"annealed layers per frame (default {TRACK_ANNEALING_LAYERS}; 1 is plain SIR)")
    t.add_argument("--resampling", default="systematic", choices=list(SCHEMES),
                   help="resampling scheme (default systematic)")
    t.add_argument("--init", help="POSES.npz whose 'poses' are the known first frames (default: ground truth, or "
                                  "the bodytrack InitialPose.txt)")
    t.add_argument("--known-frames", type=_positive_int, default=2,
                   help="known frames the filter starts from (default 2, as in Taylor 2009)")
    t.add_argument("--train-mocap", nargs="+", default=None, metavar="FILE",
                   help="mocap clips whose frame-to-frame changes set the random-walk scale (default: the shipped "
                        "subject-7 walks 07_01 and 07_02); bodytrack folders use PoseParameters.txt")
    t.add_argument("--device", default="cpu", metavar="DEVICE",
                   help="where particles are scored: cpu (default: the numpy path) or cuda, cuda:N (the GPU path: "
                        "the likelihood's kinematics, projection and image lookups, and the CRBM family's sampling)")
    t.add_argument("--out", help="output folder (required)")
    t.add_argument("--video", help="also write an overlay video of the estimates (.mp4)")
    t.add_argument("--checkpoint-every", type=_non_negative_int, default=25, metavar="K",
                   help="save the filter's state to OUTDIR/checkpoint.npz every K frames (default 25; 0: only "
                        "on Ctrl-C); removed when the run completes")
    t.add_argument("--resume", metavar="OUTDIR",
                   help="continue an interrupted run from OUTDIR/checkpoint.npz with its original settings "
                        "(give no other arguments)")
    priors = {f"prior {n}": prior_entry(n).options for n in available_priors()}
    likelihoods = {f"likelihood {n}": likelihood_entry(n).options for n in available_likelihoods()}
    shared = {o.name for opts in priors.values() for o in opts} & {o.name for opts in likelihoods.values() for o in opts}
    if shared:
        raise InputError(f"a prior and a likelihood both declare the option(s) {', '.join(sorted(shared))}; "
                         "rename one of them")
    _add_plugin_options(t, {**priors, **likelihoods})

    e = sub.add_parser("compare", parents=[plugin_flag], help="run an experiment: priors x sequences x settings x seeds, with tables",
                       description="Run every configuration of an experiment file (TOML; see "
                                   "tracker/app/experiment.py and benchmarks/experiments/) in parallel, skipping "
                                   "runs finished before, and write table.md, table.csv and per_frame.png.")
    e.add_argument("experiment", metavar="EXPERIMENT", help="experiment file (.toml)")
    e.add_argument("--out", required=True, help="output folder (runs, cached sequences and models, tables)")
    e.add_argument("--jobs", type=_positive_int, default=1, help="parallel runs (default 1)")
    e.add_argument("--backend", default="joblib", choices=["joblib", "dask", "ray"],
                   help="joblib (this machine, default), dask or ray (a local cluster, or --address)")
    e.add_argument("--address", default=None, help="scheduler address of an existing Dask or Ray cluster")

    d = sub.add_parser("demo", parents=[plugin_flag], help="render, track and score a shipped walk (the built-in default job)",
                       description="Render 1.5 s of the shipped CMU walk 07_02 into 4 cameras, train a CRBM on "
                                   "the other shipped walk, track with the zero-velocity and the CRBM prior (1000 "
                                   "particles), print both errors and write the error-per-frame plot and an "
                                   "overlay video.")
    d.add_argument("--out", default="demo_output", help="output folder (default ./demo_output)")
    d.add_argument("--frames", type=_number(int, 4, strict=False), default=90,
                   help="frames to render and track (default 90: 1.5 s)")
    return p


def _option_type(option: Option):
    """The argparse type of a plugin option: the conversion only (ranges are checked per plugin)."""
    def parse(text: str):
        try:
            return option.parse(text, option.flag)
        except InputError as exc:
            raise argparse.ArgumentTypeError(exc.reason) from None
    return parse if option.type is not str else str


def _add_plugin_options(parser: argparse.ArgumentParser, declared: dict[str, tuple[Option, ...]]) -> None:
    """One flag per option name over all plugins (default None: "not given"), its help naming each plugin's
    meaning. A plugin option whose flag the command already has is refused."""
    users: dict[str, list[str]] = {}
    first: dict[str, Option] = {}
    for plugin, options in declared.items():
        for o in options:
            users.setdefault(o.name, []).append(f"{plugin.split()[-1]}: {o.described()}")
            first.setdefault(o.name, o)
    taken = set(parser._option_string_actions)  # the command's own flags
    for name, o in first.items():
        if o.flag in taken:
            raise InputError(f"plugin option {o.flag} clashes with a flag of the {parser.prog.split()[-1]} command; "
                             "rename the option")
        text = "; ".join(users[name])
        if o.type is bool:  # --flag and --no-flag: a setting that is on by default can be turned off
            parser.add_argument(o.flag, dest=name, action=argparse.BooleanOptionalAction, default=None, help=text)
        else:
            parser.add_argument(o.flag, dest=name, type=_option_type(o), default=None,
                                metavar=o.name.upper(), help=text)


def _given_options(args: argparse.Namespace, kind: str, name: str, declared: tuple[Option, ...],
                   all_declared: dict[str, tuple[Option, ...]]) -> dict:
    """The plugin options set on the command line for plugin ``name``; a flag of another plugin is refused."""
    mine = {o.name for o in declared}
    given = {}
    for options in all_declared.values():
        for o in options:
            value = getattr(args, o.name, None)
            if value is None or o.name in given:
                continue
            if o.name not in mine:
                raise InputError(f"{o.flag} does not apply to {kind} {name}")
            given[o.name] = value
    return given


def _convert_one(mocap: str | Path, skeleton, fps: float, length_unit, out: Path):
    from data_tools.clip_io import save_converted_clip
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget

    clip = load_mocap(mocap, skeleton, length_unit)
    result = retarget(clip, fps=fps)
    with atomic_path(out) as tmp:
        save_converted_clip(result, tmp)
    return clip, result


def cmd_convert(args: argparse.Namespace) -> int:
    out = check_output_file(args.out, "the output", (".npz",))
    clip, result = _convert_one(args.mocap, args.skeleton, args.fps, args.length_unit, out)
    for note in clip.notes:
        print(f"note: {Path(args.mocap).name}: {note}", file=sys.stderr)
    print(f"{Path(args.mocap).name}: {len(result.poses)} frames at {result.fps:g} fps, "
          f"mean retarget residual {result.mean_residual:.2f} mm -> {out}")
    return 0


def cmd_synth(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from data_tools.synth import SynthConfig, synthesize

    check_output_folder(args.out, empty=not args.overwrite, replaceable=("cameras.json", "meta.json"))
    settings = SynthConfig(views=args.views, fps=args.fps, start=args.start, frames=args.frames, seed=args.seed,
                           width=args.width, height=args.height, noise=args.noise,
                           lighting_change=args.lighting_change, occluder=args.occluder,
                           missing_camera=args.missing_camera, turn=args.turn)
    clip = load_mocap(args.mocap, args.skeleton, args.length_unit)
    for note in clip.notes:
        print(f"note: {Path(args.mocap).name}: {note}", file=sys.stderr)
    result = retarget(clip, fps=args.fps)
    if args.then or args.switch_at:
        from data_tools.transition import cross_fade

        if not (args.then and args.switch_at):
            raise InputError("a transition needs both --then FILE and --switch-at FRAME")
        second = retarget(load_mocap(args.then, args.then_skeleton, args.length_unit), fps=args.fps)
        result, change = cross_fade(result, second, args.switch_at, args.fade)
        print(f"transition: {Path(args.mocap).name} until frame {change.fade_start}, cross-faded into "
              f"{Path(args.then).name} (from its frame {change.second_start}) by frame {change.switch}")
    out = synthesize(result, args.out, settings, source=result.source if args.then else str(args.mocap),
                     overwrite=args.overwrite,
                     progress=lambda it: tqdm(it, desc="rendering", unit="frame"))
    print(f"{Path(args.mocap).name}: {out.n_frames} frames x {args.views} views at "
          f"{result.fps:g} fps -> {out.root} ({out.render_seconds / out.n_frames * 1000:.0f} ms per frame "
          f"to render and write)")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    import cv2
    from tqdm import tqdm

    from data_tools.sequence import read_sequence
    from data_tools.estimates import read_poses_file
    from tracker.app.visualize import overlay_grid, write_video

    if not args.out and not args.video:
        raise InputError("nothing to write: give --out FILE.png and/or --video FILE.mp4")
    if args.out:
        check_output_file(args.out, "--out", (".png",))
    if args.video:
        check_output_file(args.video, "--video", (".mp4",))
    seq = read_sequence(args.sequence)
    if args.poses:
        poses = read_poses_file(args.poses, "poses", seq.model)
    elif seq.groundtruth is not None:
        poses = seq.groundtruth.poses
    elif seq.initial_poses is not None:
        poses = seq.initial_poses
    else:
        raise InputError("the sequence has no ground truth or initial pose; give --poses", seq.root)
    views = list(range(seq.n_views))
    seq.check_frame(args.frame)
    if args.frame >= len(poses):
        raise InputError(f"no pose for frame {args.frame}: {len(poses)} pose(s) available", args.poses or seq.root)
    truth = seq.groundtruth.poses if args.poses and seq.groundtruth is not None else None
    name = Path(args.poses).stem if args.poses else None

    def picture(k: int) -> np.ndarray:
        if args.poses:  # the estimate over the ground truth, where the sequence has one
            gt = truth[k] if truth is not None and k < len(truth) else None
            return overlay_grid(seq, poses[k], k, views, f"frame {k}", 2, truth=gt, estimate_name=name)
        return overlay_grid(seq, poses[k], k, views, f"frame {k}")

    if args.out:
        out = Path(args.out)
        with atomic_path(out) as tmp:
            if not cv2.imwrite(str(tmp), cv2.cvtColor(picture(args.frame), cv2.COLOR_RGB2BGR)):
                raise InputError("cannot write image", out)
        print(f"frame {args.frame}, {seq.n_views} views -> {out}")
    if args.video:
        n = min(seq.n_frames, len(poses))
        write_video(Path(args.video), (picture(k) for k in tqdm(range(n), desc="video", unit="frame")),
                    seq.fps or 25.0)
        print(f"{n} frames -> {args.video}")
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
    from tracker.app.compare import compare

    summary = compare(args.experiment, args.out, jobs=args.jobs, backend=args.backend, address=args.address,
                      threads=args.threads)
    print(summary["table"])
    print(f"-> {Path(args.out) / 'table.md'}, table.csv, per_frame.png")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from tracker.app.demo import run_demo

    return run_demo(Path(args.out), args.frames)


def _progress_bar(desc: str):
    """A ``progress(done, total, metrics)`` callback drawing one tqdm bar (created on the first call)."""
    from tqdm import tqdm

    state = {}

    def progress(done: int, total: int, metrics: dict) -> None:
        if "bar" not in state:
            state["bar"] = tqdm(total=total, desc=desc, unit="it")
        bar = state["bar"]
        bar.update(done - bar.n)
        bar.set_postfix({k: f"{v:.4g}" for k, v in metrics.items()})
        if done >= total:
            bar.close()

    return progress


def cmd_train(args: argparse.Namespace) -> int:
    out = check_output_file(args.out, "the model file")
    trainable = {n: prior_entry(n).train_options for n in available_priors() if prior_entry(n).train is not None}
    options = _given_options(args, "prior", args.prior, trainable[args.prior], trainable)
    print(f"training a {args.prior} prior on {len(args.mocap)} clip(s) at {args.fps:g} fps", flush=True)
    checkpoint = out.with_name(out.name + ".checkpoint")
    try:
        model = train(args.prior, args.mocap, skeletons=args.skeleton, fps=args.fps, seed=args.seed,
                      progress=_progress_bar(f"training {args.prior}"), checkpoint=checkpoint, resume=args.resume,
                      **options)
    except KeyboardInterrupt:  # Ctrl-C: the last checkpoint (if any) stays for --resume; no model is written
        if not prior_entry(args.prior).resumable:
            again = "; nothing saved"
        elif checkpoint.exists():
            again = "; continue with the same command and --resume"
        else:
            again = "; nothing saved (--checkpoint-every E saves the training state as it goes)"
        print(f"\ninterrupted{again}", file=sys.stderr)
        return 130
    with atomic_path(out) as tmp:
        model.save(tmp)
    print(f"{model.summary()} -> {out}")
    return 0


TRACK_ARGS = "track_arguments.json"


def _track_arguments(args: argparse.Namespace) -> argparse.Namespace:
    """The arguments of a run: as given (paths made absolute, kept in OUTDIR for --resume), or with --resume
    those saved by the interrupted run."""
    if args.resume:
        defaults = vars(build_parser().parse_args(["track"]))
        given = [k for k, v in vars(args).items() if k not in ("resume", "command", "plugin", "threads")
                 and v not in (None, False, [], defaults.get(k))]
        if given:
            raise InputError(f"--resume takes no other arguments (got {', '.join('--' + g for g in given)})")
        path = Path(args.resume) / TRACK_ARGS
        if not path.is_file():
            raise InputError(f"no interrupted run to resume here (no {TRACK_ARGS})", args.resume)
        from data_tools.textfiles import read_json

        saved = read_json(path, "saved track arguments")
        for spec in saved.get("plugin", []):
            import_plugin(spec)
        return argparse.Namespace(**{**vars(args), **saved, "resume": args.resume})
    if not args.sequence or not args.prior or not args.out:
        raise InputError("track needs DIR, --prior and --out (or --resume OUTDIR)")
    for key in ("sequence", "out", "video", "init"):
        if getattr(args, key):
            setattr(args, key, str(Path(getattr(args, key)).resolve()))
    for key in ("model", "train_mocap"):
        if getattr(args, key):
            setattr(args, key, [str(Path(m).resolve()) for m in getattr(args, key)])
    return args


def cmd_track(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from data_tools.estimates import read_poses_file
    from tracker.app.tracking import TrackingInterrupted
    from tracker.app.visualize import overlay_frames, write_video

    args = _track_arguments(args)
    check_output_folder(args.out)  # before any tracking, so a bad output path loses no work
    if args.video:
        check_output_file(args.video, "--video", (".mp4",))
    seq = load_sequence(args.sequence)
    views = _parse_views(args.views, seq.n_views)
    if args.frames is not None and args.frames > seq.n_frames:
        raise InputError(f"--frames {args.frames} is past the end of the sequence ({seq.n_frames} frames)", seq.root)
    priors = {n: prior_entry(n).options for n in available_priors()}
    likelihoods = {n: likelihood_entry(n).options for n in available_likelihoods()}
    prior_options = _given_options(args, "prior", args.prior, prior_entry(args.prior).options, priors)
    lik_options = _given_options(args, "likelihood", args.likelihood, likelihood_entry(args.likelihood).options,
                                 likelihoods)
    prior = build_prior(args.prior, seq, args.model or (), train_mocap=args.train_mocap, device=args.device,
                        **prior_options)
    likelihood = build_likelihood(args.likelihood, seq, views, device=args.device, **lik_options)
    init = read_poses_file(args.init, "initial poses", seq.model) if args.init else None
    T = args.frames or seq.n_frames
    given = len(init) if init is not None else 0 if seq.groundtruth is None else len(seq.groundtruth.poses)
    if min(args.known_frames, given) >= T:  # known poses of the sequence's own first frames (not bodytrack's)
        raise InputError(f"--known-frames {args.known_frames} leaves nothing to track: the run has {T} frame(s) and "
                         f"{min(args.known_frames, given)} of them would be known", seq.root)
    out = Path(args.out)
    if not args.resume:
        from data_tools.files import write_text_atomic

        saved = {k: v for k, v in vars(args).items() if k not in ("resume", "command", "threads")}
        saved["plugin"] = [str(Path(p).resolve()) if p.endswith(".py") else p for p in args.plugin]
        write_text_atomic(out / TRACK_ARGS, json.dumps(saved, indent=1))
    errors: list[float] = []
    bars: list = []  # the bar appears with the first tracked frame: a refusal before that stays one line

    def on_frame(step, err: float | None) -> None:
        if not bars:
            bars.append(tqdm(total=T, desc=f"tracking ({args.prior})", unit="frame"))
        bars[0].update(1)
        if err is not None:
            errors.append(err)
            bars[0].set_postfix(error_mm=f"{err:.0f}", mean_mm=f"{np.mean(errors):.0f}")

    try:
        run = track(seq, prior, likelihood=likelihood, particles=args.particles, views=views,
                    frames=args.frames, seed=args.seed, annealing_layers=args.annealing_layers,
                    resampling=args.resampling, known_frames=args.known_frames, init=init, on_frame=on_frame,
                    device=args.device,
                    checkpoint=out / "checkpoint.npz", checkpoint_every=args.checkpoint_every,
                    resume=bool(args.resume))
    except TrackingInterrupted as stop:
        for bar in bars:
            bar.close()
        if stop.partial is not None:
            stop.partial.settings.update(prior=args.prior, prior_models=list(args.model or ()))
            stop.partial.save(out)
        done = "" if stop.partial is None else f" after {len(stop.partial.tracked_frames)} frame(s)"
        again = f"; resume with: python -m tracker track --resume {out}" if stop.checkpoint else ""
        print(f"interrupted{done}: partial result in {out}{again}", file=sys.stderr)
        return 130
    for bar in bars:
        bar.update(T - bar.n)
        bar.close()
    run.settings["prior"] = args.prior
    run.settings["prior_models"] = [str(m) for m in (args.model or ())]
    result = run.save(out)
    (out / TRACK_ARGS).unlink(missing_ok=True)
    if run.prior_summary is not None:  # e.g. the FCRBM's posterior over style labels, per frame
        from tracker.app.visualize import summary_plot

        kind = "posterior" if run.summary_kind == "posterior" else "posterior mean"
        summary_plot(out / "prior_summary.png", run.prior_summary, f"{args.prior}: {kind} per frame")
    if run.recovered_frames:
        print(f"warning: no particle explained frame(s) {result['recovered_frames']}; the filter re-diffused "
              f"around its last estimate", file=sys.stderr)
    err = "" if run.mean_error is None else (f", mean error {result['mean_error_mm']:.1f} "
                                             f"± {result['std_error_mm']:.1f} mm")
    layers = run.settings["annealing_layers"]
    print(f"{result['frames']} frames tracked with {args.particles} particles"
          f"{f' x {layers} annealing layers' if layers > 1 else ''}, {len(views)} view(s), {args.prior}{err}, "
          f"{run.seconds_per_frame:.3f} s per frame -> {out}")
    if args.video:
        write_video(Path(args.video), overlay_frames(seq, run.poses, views, run.errors, run.first_tracked,
                                                     estimate_name=args.prior), seq.fps or 25.0)
        print(f"overlay video -> {args.video}")
    return 0


COMMANDS = {"convert": cmd_convert, "synth": cmd_synth, "show": cmd_show, "train": cmd_train, "track": cmd_track,
            "compare": cmd_compare, "demo": cmd_demo}


def _plugins_from_argv(argv: list[str]) -> list[str]:
    """``--plugin`` values, read before the parser is built (plugins add choices and flags to it)."""
    found = []
    for i, a in enumerate(argv):
        if a == "--plugin" and i + 1 < len(argv):
            found.append(argv[i + 1])
        elif a.startswith("--plugin="):
            found.append(a.split("=", 1)[1])
    return found


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        for spec in _plugins_from_argv(argv):
            import_plugin(spec)
        args = build_parser().parse_args(argv)
        if args.command != "compare":  # compare gives each worker its share instead
            set_threads(args.threads)
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (MemoryError, RuntimeError) as exc:  # sizes within the checked ranges that this machine cannot hold
        if isinstance(exc, RuntimeError) and "can't allocate memory" not in str(exc):  # torch's allocator says so
            raise
        reason = str(exc).splitlines()[0][:160] if str(exc) else "allocation failed"
        print(f"error: not enough memory for these settings ({reason}); choose smaller sizes", file=sys.stderr)
        return 2
