"""The command line's arguments: the parser of ``pose-tracker`` (the contract: README, "Commands").

Each command's own flags are declared here; the flags of the priors and likelihoods come from the registries,
for the prior (and likelihood) a command line names: ``track --prior crbm --help`` shows the CRBM's options
and no other prior's, and ``track --help`` lists the priors with one line each. A flag of another plugin than
the one named is refused in one line (:func:`parse_arguments`).
"""
from __future__ import annotations

import argparse
import difflib
import logging
import textwrap
from typing import Sequence

import numpy as np

from data_tools.checks import MAX_FPS, MAX_IMAGE_SIDE, MAX_MM_PER_UNIT, MAX_VIEWS, MIN_FPS, MIN_MM_PER_UNIT
from tracker.app.plugins import available_likelihoods, available_priors, likelihood_entry, prior_entry
from tracker.app.console import PROG, error_line
from data_tools.synth_settings import SYNTH_OPTIONS, synth_option
from tracker.app.schema import KEYPOINT_LIKELIHOOD, add_flags, add_option_flags, argument_type, setting
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
_seed = argument_type(setting("seed"))
_fps = _number(float, MIN_FPS, strict=False, maximum=MAX_FPS)
_length_unit = _number(float, MIN_MM_PER_UNIT, strict=False, maximum=MAX_MM_PER_UNIT)
_image_side = _number(int, 1, strict=False, maximum=MAX_IMAGE_SIDE)
_views = _number(int, 1, strict=False, maximum=MAX_VIEWS)
_JOINT_MAP_HELP = ("JSON or TOML file naming the file's joint for each body point (pelvis = \"Hips\", ...), for "
                   "skeletons whose names are not recognised (docs/guide/motion_capture.md)")


log = logging.getLogger(__name__)


class _Parser(argparse.ArgumentParser):
    """argparse with exit status 2 and a one-line message for usage errors, in the form of every other refusal
    (``pose-tracker: error: track: ...``, naming the command whose arguments were wrong)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        command = " ".join(self.prog.split()[1:])
        self.exit(2, error_line(f"{command}: {message}" if command else message) + "\n")


class _DeprecatedAlias(argparse.Action):
    """An old spelling of a flag, kept for one version: it sets the new flag's value and logs a warning."""

    def __init__(self, option_strings, dest, new_flag: str, why: str = "", **kwargs):
        super().__init__(option_strings, dest, **kwargs)
        self.new_flag, self.why = new_flag, why

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        command = " ".join(parser.prog.split()[1:])
        log.warning(f"{command} {option_string} is deprecated and will be removed: use {self.new_flag}"
                    f"{self.why}")
        setattr(namespace, self.dest, values)


def _verbosity_flags(parser: argparse.ArgumentParser, default) -> None:
    """``--quiet`` and ``--verbose`` (one or the other), before the command or after it."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", default=default,
                       help="show only warnings and errors: no progress bars or informational lines (results "
                            "still go to stdout)")
    group.add_argument("-v", "--verbose", action="store_true", default=default, help="show debug lines too")


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The parser; the prior and likelihood that ``argv`` names (``--prior``, ``--likelihood``) bring their own
    flags to ``train`` and ``track``."""
    from tracker import __version__

    p = _Parser(prog=PROG, description="3D human pose tracking with learned dynamical priors.")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    _verbosity_flags(p, False)
    p.add_argument("--plugin", action="append", default=[], metavar="MODULE_OR_FILE",
                   help="import a module (or .py file) that registers priors or likelihoods; repeatable")
    p.add_argument("--threads", type=_positive_int, default=None,
                   help="threads for numpy/BLAS, OpenCV and torch (default: the cores available to the process)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    plugin_flag = argparse.ArgumentParser(add_help=False)  # --plugin is read before parsing; accepted anywhere
    plugin_flag.add_argument("--plugin", action="append", default=argparse.SUPPRESS, metavar="MODULE_OR_FILE",
                             help=argparse.SUPPRESS)
    _verbosity_flags(plugin_flag, argparse.SUPPRESS)  # also after the command: pose-tracker track ... --quiet
    sub.required = True

    c = sub.add_parser("convert", parents=[plugin_flag], help="convert a mocap clip (AMC+ASF or BVH) to body-model poses and markers",
                       description="Retarget a mocap clip to the 15-cone body model and write CLIP.npz with "
                                   "poses, markers (ground truth), model_markers, fps and the body shape.")
    c.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    c.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    c.add_argument("--fps", type=_fps, default=None,
                   help="output frame rate in Hz (default: the file's own); other rates are interpolated")
    c.add_argument("--joint-map", metavar="FILE", help=_JOINT_MAP_HELP)
    c.add_argument("--length-unit", type=_length_unit, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred from the skeleton's height)")
    c.add_argument("--out", required=True, help="output .npz")
    c.add_argument("--overwrite", action="store_true", help="replace an existing output file")

    k = sub.add_parser("corpus", parents=[plugin_flag], help="list what a mocap corpus holds: clips, frames, rates, "
                                                             "labels, conventions, refused files",
                       description="Read every mocap file that the paths name (files; folders, searched "
                                   "recursively; glob patterns such as 'bandai2/*walk*.bvh') as train reads it, and "
                                   "list each clip's frames, rate, duration, skeleton naming convention, length "
                                   "unit, up axis and labels, then every refused file with its reason (all of "
                                   "them, not the first only) and a total line. Exit status 2 when a file is "
                                   "refused.")
    k.add_argument("paths", nargs="+", metavar="PATH_OR_GLOB", help="mocap files, folders or glob patterns")
    k.add_argument("--labels", metavar="PATTERN|FILE",
                   help="labels per clip: a pattern over file names such as 'dataset-2_{content}_{style}_{take}' "
                        "({key} matches a label, {} anything), or a CSV, TOML or JSON file mapping files to labels")
    k.add_argument("--json", action="store_true", help="print one JSON document (clips, refused, total) instead")

    s = sub.add_parser("synth", parents=[plugin_flag], help="render a mocap clip into a synthetic multi-view sequence",
                       description="Retarget a mocap clip, render it into a calibrated rig over a cluttered room "
                                   "and write the sequence folder (cameras.json, images/, background/, "
                                   "groundtruth.npz, meta.json).")
    s.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    s.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    s.add_argument("--out", required=True, help="output sequence folder")
    add_option_flags(s, SYNTH_OPTIONS, {"cameras": "N", "lighting_change": "FRACTION", "missing_camera": "INDEX",
                                        "turn": "DEGREES"})
    s.add_argument("--views", dest="cameras", type=argument_type(synth_option("cameras")), action=_DeprecatedAlias,
                   new_flag="--cameras N", why=" (a number of cameras; track's --views is a list of camera indices)",
                   help=argparse.SUPPRESS)  # the former --cameras, kept for one version
    s.add_argument("--joint-map", metavar="FILE", help=_JOINT_MAP_HELP)
    s.add_argument("--length-unit", type=_length_unit, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred)")
    s.add_argument("--overwrite", action="store_true", help="replace a non-empty output folder")
    s.add_argument("--then", metavar="FILE", help="a second clip the person changes to (e.g. a run after a walk): "
                                                 "cross-faded into at --switch-at")
    s.add_argument("--then-skeleton", metavar="ASF", help="ASF skeleton of --then (default: <subject>.asf beside it)")
    s.add_argument("--then-joint-map", metavar="FILE", help="joint map of --then (see --joint-map)")
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
    w.add_argument("--overwrite", action="store_true", help="replace existing files at --out and --video")

    r = sub.add_parser("train", parents=[plugin_flag], help="train a learned motion prior on mocap clips",
                       description="Retarget the clips (any subjects, each with its own skeleton) to the 15-cone "
                                   "model at --fps, convert them to the invariant representation and train the "
                                   "prior; the model file keeps its normalisation statistics and the data settings "
                                   "it was trained with.")
    trainable = [n for n in available_priors() if prior_entry(n).train is not None]
    r.formatter_class = argparse.RawDescriptionHelpFormatter
    r.usage = "%(prog)s --prior NAME --mocap PATH [PATH ...] --out MODEL [options]"
    r.description = _wrapped(r.description)
    if _chosen(argv, "--prior") not in trainable:
        r.description += "\n\n" + _catalogue("learned priors", trainable, "train")
    r.add_argument("--prior", required=True, choices=trainable, metavar="NAME", help="which prior to train")
    r.add_argument("--mocap", required=True, nargs="+", metavar="PATH",
                   help="training clips: mocap files (.amc or .bvh), folders (every mocap file in them, "
                        "recursively) or glob patterns ('bandai2/*walk*.bvh'), in sorted order; converted clips "
                        "are cached ($POSE_TRACKER_CACHE)")
    r.add_argument("--skeleton", nargs="+", metavar="ASF",
                   help="ASF skeleton(s): one for all .amc clips or one per clip (default: <subject>.asf beside each)")
    r.add_argument("--fps", type=_fps, default=60.0,
                   help="frame rate of the model (default 60, synth's); every clip is resampled to it")
    r.add_argument("--joint-map", nargs="+", metavar="FILE",
                   help="joint map(s): one for all clips or one per clip, 'none' for a clip whose joint names are "
                        "recognised (see convert --help)")
    r.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    r.add_argument("--resume", action="store_true",
                   help="continue an interrupted training from OUT.checkpoint (same arguments as before); "
                        "a training stopped before its first checkpoint starts from the beginning")
    r.add_argument("--out", required=True, help="output model file (.pt)")
    r.add_argument("--overwrite", action="store_true", help="replace an existing model file")
    _check_clashes(r, {f"prior {n}": prior_entry(n).train_options for n in trainable})
    chosen = _chosen(argv, "--prior")
    if chosen in trainable:
        _plugin_group(r, f"training options of the {chosen} prior", prior_entry(chosen).train_options)

    t = sub.add_parser("track", parents=[plugin_flag], help="track a person through a sequence with a particle filter",
                       description="Track a sequence (a pose-tracker sequence folder or PARSEC bodytrack's) with an SIR particle filter "
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
    shared = {o.name for opts in priors.values() for o in opts} & {o.name for opts in likelihoods.values() for o in opts}
    if shared:
        raise InputError(f"a prior and a likelihood both declare the option(s) {', '.join(sorted(shared))}; "
                         "rename one of them")
    _check_clashes(t, {**priors, **likelihoods})
    t.formatter_class = argparse.RawDescriptionHelpFormatter
    t.usage = "%(prog)s DIR --prior NAME [--model MODEL ...] --out OUTDIR [options]\n       %(prog)s --resume OUTDIR"
    prior = _chosen(argv, "--prior")
    t.description = _wrapped(t.description)
    if prior not in available_priors():  # the catalogue; a named prior's help names no other prior
        t.description += ("\n\n" + _catalogue("priors", available_priors(), "track") + "\n\n"
                          + _catalogue("likelihoods", available_likelihoods(), "track", "--likelihood"))
    else:
        _plugin_group(t, f"options of the {prior} prior", prior_entry(prior).options)
    likelihood = _chosen(argv, "--likelihood") or UNNAMED_LIKELIHOOD
    if likelihood in available_likelihoods():
        _plugin_group(t, f"options of the {likelihood} likelihood", likelihood_entry(likelihood).options)

    e = sub.add_parser("compare", parents=[plugin_flag], help="run an experiment: priors x sequences x settings x seeds, with tables",
                       description="Run every configuration of an experiment file (TOML; see "
                                   "tracker/app/experiment.py and benchmarks/experiments/) in parallel, skipping "
                                   "runs finished before, and write table.md, table.csv, per_frame.png and "
                                   "report.html (one self-contained page: the tables, the plot and overlay "
                                   "videos).")
    e.add_argument("experiment", metavar="EXPERIMENT", help="experiment file (.toml)")
    e.add_argument("--out", required=True,
                   help="output folder (runs, cached sequences and models, tables); an earlier compare output "
                        "is continued (finished runs are skipped)")
    e.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty output folder that is not a compare output")
    e.add_argument("--jobs", type=_positive_int, default=1, help="parallel runs (default 1)")
    e.add_argument("--backend", default="joblib", choices=["joblib", "dask", "ray"],
                   help="joblib (this machine, default), dask or ray (a local cluster, or --address)")
    e.add_argument("--address", default=None, help="scheduler address of an existing Dask or Ray cluster")
    e.add_argument("--data-root", default=None, metavar="DIR",
                   help="folder the experiment's data paths are relative to, in place of the file's data_root "
                        "(default: $POSE_TRACKER_DATA_ROOT, else the file's data_root)")
    e.add_argument("--no-videos", dest="videos", action="store_false",
                   help="leave out report.html's overlay videos of the best and the worst prior (a few seconds "
                        "each: one per sequence and view set)")

    f = sub.add_parser("fetch", parents=[plugin_flag], help="download CMU mocap trials into a data root, checked",
                       description="Download CMU motion capture trials (and their subjects' skeletons) from the "
                                   "CMU database (http://mocap.cs.cmu.edu) or a mirror into DATA_ROOT/mocap/cmu/"
                                   "<subject>/, where experiment files look for them. Each file is checked by "
                                   "parsing it (skeleton bones and lengths, the trial's frame count) before it is "
                                   "put in place; files already there that pass the check are not downloaded "
                                   "again.")
    f.add_argument("dataset", nargs="?", metavar="cmu",
                   help="the database, the only one, which may be left out: 'fetch 07_01' is 'fetch cmu 07_01'")
    f.add_argument("trials", nargs="*", metavar="TRIAL", help="CMU trials as SUBJECT_TRIAL, e.g. 07_01 16_15")
    f.add_argument("--for", dest="experiment", default=None, metavar="EXPERIMENT",
                   help="also every CMU trial this experiment file (.toml) names, into its data root")
    f.add_argument("--data-root", default=None, metavar="DIR",
                   help="folder to place the files under (default: $POSE_TRACKER_DATA_ROOT, else the experiment "
                        "file's data_root)")
    f.add_argument("--mirror", default=None, metavar="URL",
                   help="base URL of a copy laid out as http://mocap.cs.cmu.edu/subjects (URL/07/07_01.amc)")
    f.add_argument("--timeout", type=_positive_float, default=30.0,
                   help="seconds to wait for the server (default 30)")

    d = sub.add_parser("demo", parents=[plugin_flag], help="render, track and score a shipped walk: a first run that needs no data of your own",
                       description="Render 1.5 s of the shipped CMU walk 07_01 (subject 7) into 4 cameras, "
                                   "track it with the zero-velocity prior and with the recommended default, the "
                                   "mixture of the pretrained neural prior (which never saw subject 7) and "
                                   "zero-velocity, 1000 particles, tracking seeds 0, 1 and 2 each (nothing is "
                                   "trained), print every run's errors and one line saying what they show, and "
                                   "write the error-per-frame plot and an overlay video.")
    d.add_argument("--out", default="demo_output",
                   help="output folder (default ./demo_output); a folder holding an earlier demo's output (its "
                        "demo.json) is replaced whole only with --overwrite, and a non-empty folder without it never")
    d.add_argument("--overwrite", action="store_true", help="replace an earlier demo's output at --out")
    d.add_argument("--frames", type=_number(int, 4, strict=False), default=90,
                   help="frames to render and track (default 90: 1.5 s)")
    from tracker.app.video_commands import add_parsers as add_video_parsers

    add_video_parsers(sub, [plugin_flag])
    return p


def _option_type(option: Option):
    """The argparse type of a plugin option: the conversion only (ranges are checked per plugin), its message in
    argparse's form (``argument --switch: must be at least 0 and at most 0.5, got '0.9'``)."""
    def parse(text: str):
        try:
            return option.parse(text, option.flag)
        except InputError as exc:
            reason = exc.reason.removeprefix(f"{option.flag}: ").removeprefix(f"{option.name} ")
            raise argparse.ArgumentTypeError(reason) from None
    return parse if option.type is not str else str


def _wrapped(text: str) -> str:
    return textwrap.fill(text, 79)


def _catalogue(kind: str, names: Sequence[str], command: str, flag: str = "--prior") -> str:
    """One line per registered plugin, and how to see one's own options."""
    summaries = {n: (prior_entry(n) if flag == "--prior" else likelihood_entry(n)).summary for n in names}
    width = max(len(n) for n in names) + 2
    lines = [f"{kind} ({command} {flag} NAME --help shows one's own options):"]
    for name, summary in summaries.items():
        body = textwrap.wrap(summary or "", 79 - width - 2) or [""]
        lines.append(f"  {name:<{width}}{body[0]}")
        lines += [" " * (width + 2) + more for more in body[1:]]
    return "\n".join(lines)


def _chosen(argv: Sequence[str], flag: str) -> str | None:
    """The value ``argv`` gives ``flag`` (``--prior crbm`` or ``--prior=crbm``), or None."""
    argv = list(argv)
    for i, a in enumerate(argv):
        if a == flag and i + 1 < len(argv):
            return argv[i + 1]
        if a.startswith(flag + "="):
            return a.split("=", 1)[1]
    return None


def _flags(option: Option) -> list[str]:
    return [option.flag] + (["--no-" + option.flag[2:]] if option.type is bool else [])


def _check_clashes(parser: argparse.ArgumentParser, declared: dict[str, tuple[Option, ...]]) -> None:
    """Refuse a plugin option whose flag the command already has."""
    taken = set(parser._option_string_actions)  # the command's own flags
    for options in declared.values():
        for o in options:
            if o.flag in taken:
                raise InputError(f"plugin option {o.flag} clashes with a flag of the {parser.prog.split()[-1]} "
                                 "command; rename the option")


def _plugin_group(parser: argparse.ArgumentParser, title: str, options: Sequence[Option]) -> None:
    """The options of one plugin as a group of flags (default None: "not given"; the plugin applies its own)."""
    group = parser.add_argument_group(title)
    for o in options:
        if o.type is bool:  # --flag and --no-flag: a setting that is on by default can be turned off
            group.add_argument(o.flag, dest=o.name, action=argparse.BooleanOptionalAction, default=None,
                               help=o.described())
        else:
            group.add_argument(o.flag, dest=o.name, type=_option_type(o), default=None, metavar=o.name.upper(),
                               help=o.described())


#: Whose options a ``track`` command line takes when it names no likelihood: the default likelihood is chosen by
#: the sequence (:func:`tracker.app.api.default_likelihood`), and these are the options of both choices.
UNNAMED_LIKELIHOOD = KEYPOINT_LIKELIHOOD


def given_options(args: argparse.Namespace, declared: Sequence[Option]) -> dict:
    """The options of one plugin set on the command line (or in a resumed run's saved arguments)."""
    return {o.name: getattr(args, o.name) for o in declared if getattr(args, o.name, None) is not None}


def _refuse_foreign_flags(argv: Sequence[str]) -> None:
    """A flag of a prior or likelihood that the command line does not name is refused in one line."""
    if not argv or argv[0] not in ("train", "track"):
        return
    command = argv[0]
    prior, likelihood = _chosen(argv, "--prior"), _chosen(argv, "--likelihood") or UNNAMED_LIKELIHOOD
    owners: dict[str, list[str]] = {}
    for name in available_priors():
        entry = prior_entry(name)
        for o in (entry.train_options if command == "train" else entry.options):
            for flag in _flags(o):
                owners.setdefault(flag, []).append(f"prior {name}")
    if command == "track":
        for name in available_likelihoods():
            for o in likelihood_entry(name).options:
                for flag in _flags(o):
                    owners.setdefault(flag, []).append(f"likelihood {name}")
    mine = {f"prior {prior}", f"likelihood {likelihood}"}
    for token in argv[1:]:
        flag = token.split("=", 1)[0]
        if flag in owners and not mine & set(owners[flag]):
            if prior is None:
                raise InputError(f"{flag} is an option of {', '.join(owners[flag])}: name the prior with --prior")
            raise InputError(f"{flag} does not apply to prior {prior}"
                             + ("" if command == "train" else f" or likelihood {likelihood}"))


def parse_arguments(argv: Sequence[str]) -> argparse.Namespace:
    """The parsed command line (plugins already imported); usage errors exit with status 2 and one line."""
    argv = list(argv)
    command = next((i for i, a in enumerate(argv) if a in ("train", "track")), None)
    if command is not None:
        _refuse_foreign_flags(argv[command:])
    parser = build_parser(argv)
    args, extra = parser.parse_known_args(argv)
    if extra:  # what argparse would refuse, with the nearest flag of the command named (a typo, say)
        command_parser = _command_parser(parser, getattr(args, "command", None))
        command_parser.error(f"unrecognized arguments: {' '.join(extra)}{_suggestion(extra, command_parser)}")
    return args


def _command_parser(parser: argparse.ArgumentParser, command: str | None) -> argparse.ArgumentParser:
    """The parser of ``command`` (the top-level one when there is none)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            return action.choices[command]
    return parser


def _suggestion(extra: Sequence[str], parser: argparse.ArgumentParser) -> str:
    """`` (did you mean --particles?)`` for the first unrecognised flag that is close to one ``parser`` takes,
    else nothing."""
    flags = [f for f in parser._option_string_actions if f.startswith("--")]
    for token in extra:
        if token.startswith("--"):
            close = difflib.get_close_matches(token.split("=", 1)[0], flags, n=1, cutoff=0.75)
            if close:
                return f" (did you mean {close[0]}?)"
    return ""
