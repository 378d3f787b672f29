"""``pose-tracker import-video``: turn one video per calibrated camera into a sequence folder."""
from __future__ import annotations

import argparse
import logging
from typing import Sequence

from data_tools.vision.import_settings import IMPORT_OPTIONS
from tracker.app.schema import add_option_flags

log = logging.getLogger(__name__)

NAME = "import-video"


def camera_video_pairs(text: str) -> dict[str, str]:
    """``cam_01=left.mp4,cam_02=right.mp4`` -> {camera: video}."""
    out = {}
    for item in (t for t in text.split(",") if t.strip()):
        if "=" not in item:
            raise argparse.ArgumentTypeError(f"expected CAMERA=VIDEO pairs separated by commas, got {item!r}")
        cam, video = (s.strip() for s in item.split("=", 1))
        out[cam] = video
    if not out:
        raise argparse.ArgumentTypeError("expected CAMERA=VIDEO pairs separated by commas")
    return out


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub`` (``argv``: the whole command line)."""
    v = sub.add_parser("import-video", parents=parents,
                       help="turn one video per calibrated camera into a sequence folder",
                       description="Decode one video per camera into a sequence folder (cameras.json, images/, "
                                   "meta.json) that track reads once it has silhouettes. The calibration may be "
                                   "Pose2Sim/anipose TOML, Qualisys .qca.txt, OpenCV FileStorage .yml/.xml "
                                   "(two files allowed: --calibration twice) or cameras.json. Videos go to the "
                                   "cameras in sorted name order unless --map pairs them.")
    v.add_argument("videos", nargs="+", metavar="VIDEO", help="one video file per camera (anything OpenCV reads)")
    v.add_argument("--calibration", action="append", required=True, metavar="FILE",
                   help="calibration file (repeat for OpenCV intrinsics + extrinsics files)")
    v.add_argument("--out", required=True, help="output sequence folder")
    add_option_flags(v, IMPORT_OPTIONS, {"downscale": "F", "frames": "A:B"})
    v.add_argument("--map", type=camera_video_pairs, metavar="CAM=VIDEO,...",
                   help="pair cameras with videos by name (cameras left out are not imported)")
    v.add_argument("--overwrite", action="store_true", help="replace an existing sequence folder at --out")
    return v


def run(args: argparse.Namespace) -> int:
    from data_tools.io.files import check_output_folder
    from data_tools.vision.video import import_videos

    check_output_folder(args.out, empty=not args.overwrite, replaceable=("cameras.json",))
    calibration = args.calibration[0] if len(args.calibration) == 1 else args.calibration
    result = import_videos(calibration, args.videos, args.out, downscale=args.downscale, frames=args.frames,
                           mapping=args.map)
    for note in result.notes:
        log.info(note)
    print(f"{len(result.rig)} cameras x {result.n_frames} frames at {result.fps:g} Hz "
          f"(video frames {result.start}:{result.stop}) -> {result.root}")
    return 0
