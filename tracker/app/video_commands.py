"""Commands for real video: ``import-video`` (videos and a calibration to a sequence folder), ``silhouettes``,
``keypoints`` (2-D keypoints detected, or read from another tool's files), ``initialise`` and ``export``
(tracked poses to BVH or TRC). :func:`add_parsers` adds their parsers, :data:`COMMANDS` maps names to handlers."""
from __future__ import annotations

import argparse
import logging
from pathlib import Path

from data_tools.keypoints.layouts import LAYOUTS
from data_tools.person_segmentation import INSTALL as SEGMENTATION_INSTALL
from tracker.core.errors import InputError

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

    m = sub.add_parser("silhouettes", parents=parents,
                       help="write the person's silhouettes of a sequence that has no background plate",
                       description="Write masks/<camera>/NNNNNN.png, which track then uses. --method median "
                                   "learns each camera's background from the sequence's own frames (the "
                                   "per-pixel median of up to 25 frames) and subtracts it: it needs a person who "
                                   "moves. --method person runs a person-segmentation model (MediaPipe's "
                                   f"BlazePose, an optional package: {SEGMENTATION_INSTALL}) and "
                                   "finds a person who stands still too. Either keeps the largest region. Masks "
                                   "of your own go in masks/<camera>/ (non-zero = person, one PNG per frame, "
                                   "named as the images).")
    m.add_argument("sequence", metavar="DIR", help="sequence folder (e.g. written by import-video)")
    m.add_argument("--method", choices=("median", "person"), default=None,
                   help="median: background learnt from the frames (a person who moves); person: a "
                        "person-segmentation model (a person who may stand still). Default: person where "
                        "MediaPipe is installed and finds a person in every camera's first frame, else median")
    m.add_argument("--overwrite", action="store_true", help="replace masks/ where the sequence has it")

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

    i = sub.add_parser("initialise", parents=parents,
                       help="fit the body's size and first poses to a sequence's keypoints or first silhouettes",
                       description="For a sequence with keypoints (pose-tracker keypoints): measure the body's "
                                   "limbs from the keypoints triangulated over the views and fit the first "
                                   "poses' 40 numbers to the keypoints in every view (one view: the default "
                                   "body, placed by its height in the image). Otherwise: search the floor position, heading, body scale and stance (standing, "
                                   "A-pose, T-pose; or around --near, an approximate pose of your own) that the "
                                   "tracker's likelihood rates best on the first frame's silhouettes, refine "
                                   "every pose number from both headings (silhouettes hardly tell front from "
                                   "back), write the fitted body shape into the sequence's "
                                   "meta.json (which track then uses) and the first poses to --out, for track "
                                   "--init. --proportions landmarks measures the person's upper arms, forearms, "
                                   "thighs and shanks from BlazePose's landmarks triangulated over the first "
                                   "frames' views and keeps that body instead of searching the scale.")
    i.add_argument("sequence", metavar="DIR", help="sequence folder with silhouettes (masks/) or plates")
    i.add_argument("--out", required=True, metavar="FILE", help="poses file to write (.npz, for track --init)")
    i.add_argument("--overwrite", action="store_true", help="replace an existing poses file at --out")
    i.add_argument("--near", metavar="POSES.npz", help="an approximate first pose to search around")
    i.add_argument("--frames", type=int, default=2, metavar="N",
                   help="how many first frames the pose is written for (track's --known-frames; default 2)")
    i.add_argument("--seed", type=int, default=0, help="random seed of the local search (default 0)")
    i.add_argument("--evidence", choices=("keypoints", "silhouettes"), default=None,
                   help="what the start is fitted to: keypoints (the default for a sequence with keypoints: the "
                        "body measured from the keypoints triangulated over the views, the pose fitted to them) "
                        "or silhouettes (the default otherwise: the search described above)")
    i.add_argument("--proportions", choices=("scale", "landmarks"), default="scale",
                   help="scale: the default adult's proportions at the scale the silhouettes fit best "
                        "(default); landmarks: the person's own segment lengths, measured from BlazePose's "
                        "landmarks triangulated over the first frames' views (needs the package silhouettes "
                        "--method person needs)")

    c = sub.add_parser("capture", parents=parents,
                       help="calibrated videos in, tracked poses out: every step in one command",
                       description="Import the videos, write the person's silhouettes, detect 2-D keypoints, "
                                   "fit the body's size and first poses to them, track with the recommended "
                                   "prior and the keypoint and silhouette likelihoods, and write OUT/poses.trc, "
                                   "OUT/poses.bvh, OUT/triangulated.trc (the keypoints triangulated, with two "
                                   "or more views), OUT/overlay.mp4 and OUT/result.json. A rerun skips the "
                                   "steps already done. Needs MediaPipe (" + SEGMENTATION_INSTALL + ").")
    c.add_argument("videos", nargs="+", metavar="VIDEO", help="one video file per camera, paired by sorted name")
    c.add_argument("--calibration", required=True, metavar="FILE", help="the cameras' calibration file")
    c.add_argument("--out", required=True, metavar="DIR", help="output folder")
    c.add_argument("--views", metavar="LIST",
                   help="cameras to use, as indices into the calibration's (e.g. 0,2 or 1 alone; default all)")
    c.add_argument("--prior", default=None, metavar="NAME", help="motion prior (default mixture: the shipped "
                                                                 "neural prior with zero-velocity)")
    c.add_argument("--particles", type=int, default=None, metavar="N", help="particles (default 1000)")
    c.add_argument("--seed", type=int, default=0, help="random seed of the tracking (default 0)")
    c.add_argument("--downscale", type=_downscale, default=None, metavar="F",
                   help="shrink every frame by F before everything else (default 4)")
    c.add_argument("--frames", metavar="A:B", help="video frames A to B-1 (default: all the videos share)")
    c.add_argument("--overwrite", action="store_true",
                   help="start again in a folder holding a capture of other videos or views")

    x = sub.add_parser("export", parents=parents, help="write a tracked run's poses as BVH and/or TRC",
                       description="Write the poses of a tracked run (its folder, with result.json and "
                                   "estimates.npz) as BVH (a skeleton of the body model's links; y up, --unit, "
                                   "default metres: Blender's importer reads it at life size) and/or TRC (the 15 "
                                   "markers, y up, metres, OpenSim's and Pose2Sim's axes: TRC X, Y, Z = our y, "
                                   "z, x).")
    x.add_argument("run", metavar="RUN", help="a folder written by track (result.json, estimates.npz)")
    x.add_argument("--bvh", metavar="FILE", help="write the poses as BVH here (.bvh)")
    x.add_argument("--trc", metavar="FILE", help="write the markers as TRC here (.trc)")
    x.add_argument("--unit", choices=("m", "cm", "mm"), default="m", help="BVH length unit (default m)")
    x.add_argument("--overwrite", action="store_true", help="replace existing files at --bvh and --trc")
    x.add_argument("--sequence", metavar="DIR",
                   help="the tracked sequence (default: the one result.json names; its body shape is used)")

    r = sub.add_parser("compare-trc", parents=parents,
                       help="compare a tracked run with a reference reconstruction in a TRC file",
                       description="Map the reference's keypoints to the body model's markers (Pose2Sim / "
                                   "OpenPose names: thorax = Neck, head = Head, and the limbs' joints; the pelvis "
                                   "is left out), align the whole estimate to the reference with one "
                                   "rigid transform, and print the mean distance per joint and overall (mm). The "
                                   "reference's keypoints are not the model's markers (a hip keypoint is not "
                                   "the hip joint centre): the distances include that difference.")
    r.add_argument("run", metavar="RUN", help="a folder written by track (estimates.npz)")
    r.add_argument("reference", metavar="TRC", help="reference reconstruction (.trc)")
    r.add_argument("--offset", type=int, default=None, metavar="N",
                   help="reference frame of the estimate's first frame (default: the first video frame the "
                        "sequence was imported from, else 0)")


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


def cmd_silhouettes(args: argparse.Namespace) -> int:
    from data_tools.sequence import OWN, read_sequence
    from tracker.app.silhouettes import default_method, write_sequence_masks

    seq = read_sequence(args.sequence)
    if seq.layout != OWN:
        raise InputError("silhouettes are written into sequence folders of this toolkit's layout only",
                         args.sequence)
    if seq.mask_paths is not None and not args.overwrite:
        raise InputError("the sequence already has masks/ (pass --overwrite to replace them)", args.sequence)
    method = args.method or default_method(seq)  # (runs the person model: after the refusals)
    fractions = write_sequence_masks(seq, method)
    for cam, f in zip(seq.rig.names, fractions):
        log.info(f"{cam}: the person covers {100 * f:.1f}% of the image on average")
    print(f"{seq.n_views} cameras x {seq.n_frames} frames of silhouettes ({method}) -> {seq.root / 'masks'}")
    return 0


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


def cmd_keypoints(args: argparse.Namespace) -> int:
    from data_tools.keypoint_file import keypoints_path, write_keypoints
    from data_tools.keypoints.readers import found_share

    path = keypoints_path(args.sequence)
    if path.exists() and not args.overwrite:
        raise InputError("the sequence already has keypoints (pass --overwrite to replace them)", path)
    if args.sources:
        from data_tools.keypoints.readers import import_keypoints

        keypoints = import_keypoints(args.sequence, args.sources, args.layout)
    else:
        if args.layout:
            raise InputError("--layout names the layout of files read with --from; the detector knows its own")
        try:
            from data_tools.keypoints.detect import detect_sequence_keypoints
        except ModuleNotFoundError as exc:
            if exc.name != "data_tools.keypoints.detect":
                raise
            raise InputError("this installation has no keypoint detector: read keypoints from another tool with "
                             "--from PATH ...") from None
        from data_tools.keypoints.readers import check_keypoint_layout
        from data_tools.sequence import read_sequence

        seq = read_sequence(args.sequence, keypoints=False)  # the file this replaces may be broken
        check_keypoint_layout(seq)
        keypoints = detect_sequence_keypoints(seq, progress=_count_bar("keypoints", "image"))
        write_keypoints(seq.root, keypoints)
    source = keypoints.source
    detector = " ".join(str(s) for s in (source.get("detector", "detector"), source.get("version")) if s)
    layout = f", {source['layout']} layout" if source.get("layout") else ""
    print(f"{keypoints.n_frames} frames x {len(keypoints.cameras)} views of keypoints ({detector}{layout}): "
          f"{100 * found_share(keypoints):.0f}% of the keypoints found -> {path}")
    return 0


def _write_poses(path: str, poses) -> None:
    """``poses`` ``F x D`` written to ``path`` (.npz, ``poses``) whole, or ``path`` left as it was."""
    import numpy as np

    from data_tools.files import atomic_path

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, poses=poses)


def cmd_initialise(args: argparse.Namespace) -> int:
    import numpy as np

    from data_tools.estimates import read_poses_file
    from data_tools.files import check_output_file
    from data_tools.sequence import OWN, read_sequence, write_meta
    from tracker.app.initialise import initialise, limb_lengths

    check_output_file(args.out, "--out", (".npz",), new=not args.overwrite)
    if args.frames < 1:
        raise InputError(f"--frames must be at least 1, got {args.frames}")
    seq = read_sequence(args.sequence)
    if seq.layout != OWN:
        raise InputError("initialise writes the fitted shape into meta.json: this toolkit's layout only",
                         args.sequence)
    evidence = args.evidence or ("keypoints" if seq.keypoints is not None else "silhouettes")
    if evidence == "keypoints":
        if args.near is not None or args.proportions != "scale":
            raise InputError("--near and --proportions apply to a start from silhouettes (--evidence silhouettes)")
        from tracker.app.keypoint_start import initialise_from_keypoints

        start = initialise_from_keypoints(seq, known_frames=args.frames)
        meta = dict(seq.meta)
        meta["body_shape"] = start.shape.to_dict()
        write_meta(seq.root, meta)
        _write_poses(args.out, start.poses)
        lengths = ", ".join(f"{k} {v:.0f}" for k, v in start.lengths.items())
        log.info(f"standing height {start.height:.0f} mm" + (f"; measured {lengths} mm" if lengths else ""))
        print(f"first poses fitted to the keypoints (cost {start.cost:.1f}) -> {args.out}; body shape -> "
              f"{seq.root / 'meta.json'}")
        return 0
    near = None if args.near is None else read_poses_file(args.near, "--near", seq.model)[0]
    shape = None
    if args.proportions == "landmarks":
        from data_tools.landmarks import measure, sequence_landmarks, shape_from_landmarks

        measured = measure(seq.rig, sequence_landmarks(seq), seq.root)
        shape = shape_from_landmarks(measured.lengths, seq.root)
        log.info(f"landmarks of {len(measured.points)} frames, reprojection error {np.nanmedian(measured.errors):.1f} "
                 f"pixels (median): " + ", ".join(f"{k} {v:.0f}" for k, v in measured.lengths.items()) + " mm")
    found = initialise(seq, 0, near=near, seed=args.seed, shape=shape)
    meta = dict(seq.meta)
    meta["body_shape"] = found.shape.to_dict()
    write_meta(seq.root, meta)
    _write_poses(args.out, np.tile(found.pose, (args.frames, 1)))
    lengths = ", ".join(f"{k} {v:.0f}" for k, v in limb_lengths(found.model, found.pose).items())
    log.info(f"stance {found.stance}, scale {found.scale:g}: standing height {found.height:.0f} mm; {lengths} mm")
    print(f"first pose (log-likelihood {found.score:.1f}) -> {args.out}; body shape -> {seq.root / 'meta.json'}")
    return 0


def _run_files(run: str) -> tuple[Path, dict]:
    """A track output folder's estimates.npz and its result.json (empty when absent)."""
    from data_tools.textfiles import read_json

    folder = Path(run)
    if not (folder / "estimates.npz").is_file():
        raise InputError("not a tracked run: no estimates.npz", folder)
    result = read_json(folder / "result.json", "result.json") if (folder / "result.json").is_file() else {}
    return folder / "estimates.npz", result if isinstance(result, dict) else {}


def _run_sequence(result: dict, given: str | None, run: str):
    from data_tools.sequence import read_sequence

    path = given or result.get("sequence")
    if not path:
        raise InputError("result.json names no sequence: give --sequence DIR", run)
    return read_sequence(path)


def cmd_export(args: argparse.Namespace) -> int:
    from data_tools.bvh_export import write_bvh
    from data_tools.estimates import read_poses_file
    from data_tools.files import check_output_file
    from data_tools.trc import write_trc
    from tracker.core.kinematics import markers

    if not args.bvh and not args.trc:
        raise InputError("nothing to write: give --bvh FILE.bvh and/or --trc FILE.trc")
    for path, flag, ext in ((args.bvh, "--bvh", ".bvh"), (args.trc, "--trc", ".trc")):
        if path:
            check_output_file(path, flag, (ext,), new=not args.overwrite)
    estimates, result = _run_files(args.run)
    seq = _run_sequence(result, args.sequence, args.run)
    poses = read_poses_file(estimates, "estimates", seq.model)
    fps = seq.fps or 60.0
    if args.bvh:
        write_bvh(args.bvh, seq.model, poses, fps, unit=args.unit)
        print(f"{len(poses)} frames at {fps:g} Hz -> {args.bvh} (BVH, y up, {args.unit})")
    if args.trc:
        write_trc(args.trc, seq.model.marker_names, markers(seq.model, poses), fps)
        print(f"{len(poses)} frames at {fps:g} Hz -> {args.trc} (TRC, y up, m)")
    return 0


def cmd_compare_trc(args: argparse.Namespace) -> int:
    from data_tools.checks import load_npz
    from data_tools.reference import compare_to_trc, reference_offset

    estimates, result = _run_files(args.run)
    markers = load_npz(estimates, "estimates", ("markers",))["markers"]
    offset = args.offset
    if offset is None:
        offset = reference_offset(_run_sequence(result, None, args.run).meta) if result.get("sequence") else 0
    print(compare_to_trc(markers, args.reference, offset=offset).table())
    return 0


def cmd_capture(args: argparse.Namespace) -> int:
    from tracker.app.capture import DEFAULT_DOWNSCALE, DEFAULT_PARTICLES, DEFAULT_PRIOR, STEPS, capture

    views = None
    if args.views is not None:
        try:
            views = [int(v) for v in args.views.split(",") if v.strip()]
        except ValueError:
            raise InputError(f"--views must be comma-separated camera indices, got {args.views!r}") from None
    if args.particles is not None and args.particles < 1:
        raise InputError(f"--particles must be at least 1, got {args.particles}")
    done = []

    def on_step(step: str, line: str) -> None:
        done.append(step)
        log.info(f"[{len(done)}/{len(STEPS)}] {step}: {line}")

    result = capture(args.videos, args.calibration, args.out, views=views, prior=args.prior or DEFAULT_PRIOR,
                     seed=args.seed, particles=args.particles or DEFAULT_PARTICLES,
                     downscale=args.downscale or DEFAULT_DOWNSCALE, frames=args.frames, overwrite=args.overwrite,
                     on_step=on_step)
    print(", ".join(sorted(p.name for p in result.files.values() if p.is_file())) + f" -> {result.out}")
    return 0


COMMANDS = {"capture": cmd_capture, "import-video": cmd_import_video, "silhouettes": cmd_silhouettes, "keypoints": cmd_keypoints,
            "initialise": cmd_initialise, "export": cmd_export, "compare-trc": cmd_compare_trc}

