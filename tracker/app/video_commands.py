"""Commands for real video: ``import-video`` (videos and a calibration to a sequence folder) and ``export``
(tracked poses to BVH or TRC). :func:`add_parsers` adds their parsers, :data:`COMMANDS` maps names to handlers."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

log = logging.getLogger(__name__)


def _mapping(text: str) -> dict[str, str]:
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


def _downscale(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not 1.0 <= value <= 64.0:
        raise argparse.ArgumentTypeError(f"must be between 1 and 64, got {text}")
    return value


def add_parsers(sub, parents) -> None:
    """The parsers of this module's commands, added to the ``pose-tracker`` subcommands ``sub``."""
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
    v.add_argument("--downscale", type=_downscale, default=1.0, metavar="F",
                   help="shrink every frame by F (1 to 64, default 1), intrinsics scaled to match")
    v.add_argument("--frames", metavar="A:B",
                   help="video frames A to B-1 (required when the videos' frame counts differ)")
    v.add_argument("--map", type=_mapping, metavar="CAM=VIDEO,...",
                   help="pair cameras with videos by name (cameras left out are not imported)")
    v.add_argument("--overwrite", action="store_true", help="replace an existing sequence folder at --out")


def cmd_import_video(args: argparse.Namespace) -> int:
    from data_tools.files import check_output_folder
    from data_tools.video import import_videos

    check_output_folder(args.out, empty=not args.overwrite, replaceable=("cameras.json",))
    calibration = args.calibration[0] if len(args.calibration) == 1 else args.calibration
    result = import_videos(calibration, args.videos, args.out, downscale=args.downscale, frames=args.frames,
                           mapping=args.map)
    for note in result.notes:
        log.info(note)
    print(f"{len(result.rig)} cameras x {result.n_frames} frames at {result.fps:g} Hz "
          f"(video frames {result.start}:{result.stop}) -> {result.root}")
    return 0


COMMANDS = {"import-video": cmd_import_video}

