"""``pose-tracker keypoints``: write a sequence's 2-D keypoints: detected, or read from another tool's files."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.vision.keypoints.layouts import LAYOUTS

log = logging.getLogger(__name__)

NAME = "keypoints"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    k = sub.add_parser("keypoints", parents=parents,
                       help="write a sequence's 2-D keypoints: detected, or read from another tool's files",
                       description="Write keypoints/keypoints.npz, the body keypoints of every frame and camera. "
                                   "Without --from a detector finds them in the sequence's images. With --from "
                                   "they are read from another tool: OpenPose-style JSON, a folder of one file per "
                                   "frame per camera (OpenPose, Pose2Sim, EasyMocap, Sports2D; of several people "
                                   "the one with the largest summed confidence is taken), or an array file (.npy "
                                   "T x V x J x 3, or T x J x 3 for one camera: x, y, confidence; .npz with "
                                   "'points' and optionally 'layout' and 'cameras'). Sources follow the "
                                   "sequence's camera order, or are given as CAMERA=PATH. Their pixels are those "
                                   "of the full-resolution videos and their frame k is video frame k: both are "
                                   "converted with the downscale and first video frame import-video wrote into "
                                   "meta.json. Prints the frames, views, detector and the share of keypoints "
                                   "found.")
    k.add_argument("sequence", metavar="DIR", help="sequence folder (e.g. written by import-video)")
    k.add_argument("--from", dest="sources", nargs="+", action="extend", metavar="PATH",
                   help="read keypoints from these folders of JSON files or array files, one per camera in the "
                        "sequence's camera order, or CAMERA=PATH each (instead of detecting them)")
    k.add_argument("--layout", choices=tuple(LAYOUTS),
                   help="the other tool's keypoint layout (needed for 25 points: OpenPose's body_25 or "
                        "body_25b; inferred from 17, 26 or 33 points)")
    k.add_argument("--overwrite", action="store_true", help="replace keypoints/keypoints.npz where the sequence "
                                                            "has it")
    return k


def _count_bar(desc: str, unit: str):
    """A ``progress(done, total)`` callback drawing one bar, created at the first call (none under ``--quiet``)."""
    from tracker.app.console import progress_bar

    state = {}

    def progress(done: int, total: int) -> None:
        if "bar" not in state:
            state["bar"] = progress_bar(total=total, desc=desc, unit=unit)
        state["bar"].update(done - state["bar"].n)
        if done >= total:
            state["bar"].close()

    return progress


def run(args: argparse.Namespace) -> int:
    from data_tools.sequences.keypoint_file import keypoints_path
    from data_tools.vision.keypoints.readers import found_share
    from tracker.app.preparation import write_sequence_keypoints

    keypoints = write_sequence_keypoints(args.sequence, sources=args.sources, layout=args.layout,
                                         overwrite=args.overwrite, progress=_count_bar("keypoints", "image"),
                                         overwrite_flag="--overwrite")
    source = keypoints.source
    detector = " ".join(str(s) for s in (source.get("detector", "detector"), source.get("version")) if s)
    layout = f", {source['layout']} layout" if source.get("layout") else ""
    print(f"{keypoints.n_frames} frames x {len(keypoints.cameras)} views of keypoints ({detector}{layout}): "
          f"{100 * found_share(keypoints):.0f}% of the keypoints found -> {keypoints_path(args.sequence)}")
    return 0
