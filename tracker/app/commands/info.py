"""``pose-tracker info DIR``: what a sequence folder holds, before tracking it."""
from __future__ import annotations

import argparse
import json
from typing import Sequence

NAME = "info"


def add_parser(sub, parents: list, argv: Sequence[str]) -> argparse.ArgumentParser:
    """This command's parser, added to ``pose-tracker``'s commands ``sub``."""
    parser = sub.add_parser(NAME, parents=parents, help="say what a sequence folder holds: cameras, frames, "
                                                        "ground truth, silhouettes, keypoints",
                            description="Read a sequence folder (this toolkit's layout or PARSEC bodytrack's) as "
                                        "track reads it and print its layout, frames and frame rate, each "
                                        "camera's name and image size, and what the tracker will use: ground "
                                        "truth, background plates, silhouettes, 2-D keypoints, the body shape "
                                        "in meta.json.")
    parser.add_argument("sequence", metavar="DIR", help="sequence folder")
    parser.add_argument("--json", action="store_true", help="print one JSON document instead")
    return parser


def run(args: argparse.Namespace) -> int:
    from tracker.app.api import load_sequence

    seq = load_sequence(args.sequence)
    facts = {
        "sequence": str(seq.root), "layout": seq.layout, "frames": seq.n_frames, "fps": seq.fps,
        "cameras": [{"name": c.name, "width": c.width, "height": c.height} for c in seq.rig.cameras],
        "ground truth": seq.groundtruth is not None, "background plates": seq.background_paths is not None,
        "silhouettes": seq.mask_paths is not None, "keypoints": seq.keypoints is not None,
        "body shape": "body_shape" in seq.meta,
    }
    if args.json:
        print(json.dumps(facts, indent=1))
        return 0
    rate = f"{seq.fps:g} Hz" if seq.fps else "no frame rate"
    print(f"{seq.root}: {seq.layout} layout, {seq.n_frames} frames, {rate}")
    for camera in facts["cameras"]:
        print(f"  {camera['name']}: {camera['width']} x {camera['height']} pixels")
    print("has: " + (", ".join(k for k, v in facts.items() if v is True) or "nothing but images"))
    return 0
