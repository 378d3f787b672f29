"""``pose-tracker synth``: render a mocap clip into a synthetic multi-view sequence."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.io.files import check_output_folder
from data_tools.synthesis.synth_settings import SYNTH_OPTIONS, synth_option
from tracker.app.commands.arguments import JOINT_MAP_HELP, DeprecatedAlias, length_unit_type, positive_int
from tracker.app.console import progress_bar
from tracker.app.schema import add_option_flags, argument_type
from tracker.core.errors import InputError

log = logging.getLogger(__name__)

NAME = "synth"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    s = sub.add_parser("synth", parents=parents, help="render a mocap clip into a synthetic multi-view sequence",
                       description="Retarget a mocap clip, render it into a calibrated rig over a cluttered room "
                                   "and write the sequence folder (cameras.json, images/, background/, "
                                   "groundtruth.npz, meta.json).")
    s.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    s.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    s.add_argument("--out", required=True, help="output sequence folder")
    add_option_flags(s, SYNTH_OPTIONS, {"cameras": "N", "lighting_change": "FRACTION", "missing_camera": "INDEX",
                                        "turn": "DEGREES"})
    s.add_argument("--views", dest="cameras", type=argument_type(synth_option("cameras")), action=DeprecatedAlias,
                   new_flag="--cameras N", why=" (a number of cameras; track's --views is a list of camera indices)",
                   help=argparse.SUPPRESS)  # the former --cameras, kept for one version
    s.add_argument("--joint-map", metavar="FILE", help=JOINT_MAP_HELP)
    s.add_argument("--length-unit", type=length_unit_type, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred)")
    s.add_argument("--overwrite", action="store_true", help="replace a non-empty output folder")
    s.add_argument("--then", metavar="FILE", help="a second clip the person changes to (e.g. a run after a walk): "
                                                 "cross-faded into at --switch-at")
    s.add_argument("--then-skeleton", metavar="ASF", help="ASF skeleton of --then (default: <subject>.asf beside it)")
    s.add_argument("--then-joint-map", metavar="FILE", help="joint map of --then (see --joint-map)")
    s.add_argument("--switch-at", type=positive_int, default=None, metavar="FRAME",
                   help="with --then: the frame (output rate, before --start) where the second clip has taken over")
    s.add_argument("--fade", type=positive_int, default=12, metavar="FRAMES",
                   help="with --then: frames of the cross-fade before --switch-at (default 12)")
    return s


def run(args: argparse.Namespace) -> int:
    from data_tools.synthesis.synth_settings import SYNTH_OPTIONS
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
