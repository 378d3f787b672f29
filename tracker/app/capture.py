"""Calibrated videos in, tracked poses out, in one call: ``capture(videos, calibration, out)``.

The steps, each with its defaults, each skipped when a rerun finds it done (with the same settings) and no
step it follows from had to run again:

1. **import** the videos (:func:`data_tools.vision.video.import_videos`, shrunk by ``downscale``) into
   ``out/sequence``; with ``views``, only those cameras (indices into the calibration's cameras, in its order);
2. **silhouettes** of the person (:func:`tracker.app.silhouettes.write_sequence_masks`, the method of
   :func:`tracker.app.silhouettes.default_method`);
3. **keypoints** detected in every frame and view
   (:func:`data_tools.vision.keypoints.detect.detect_sequence_keypoints`);
4. **start**: the body's size and first poses from the keypoints (:func:`tracker.app.keypoint_start.
   initialise_from_keypoints`), written to ``out/init.npz`` and the body shape into the sequence's ``meta.json``;
5. **track** with the prior (default the recommended ``mixture``: the shipped neural prior with zero-velocity)
   and the keypoint and silhouette likelihood together, into ``out/run`` (``result.json``, ``estimates.npz``);
6. **export**: ``out/poses.trc`` and ``out/poses.bvh`` (the tracked body), ``out/triangulated.trc`` (the
   keypoints triangulated robustly and median-filtered, with two or more views: the baseline to compare the
   tracked poses with), ``out/overlay.mp4`` (the estimate over every view) and ``out/result.json`` (the
   settings, what each step took, and the paths).

Every file is written whole or not at all; a stopped capture resumes where it stopped.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from data_tools.vision.import_settings import import_option
from likelihoods.ground_contact import GROUND_OPTIONS
from tracker.app.schema import setting
from tracker.core.errors import InputError
from tracker.engine.registry import Option

#: The settings of a capture, declared once: ``pose-tracker capture``'s flags and :func:`capture`'s keywords (and
#: defaults) derive from them; ``particles`` and ``seed`` are tracking's own settings.
CAPTURE_OPTIONS: tuple[Option, ...] = (
    Option("views", int, None, "cameras to use, as indices into the calibration's (e.g. 0,2 or 1 alone; default "
           "all)", minimum=0, many=True),
    Option("prior", str, "mixture", "motion prior (default mixture: the shipped neural prior with zero-velocity)"),
    setting("particles"),
    replace(setting("seed"), help="random seed of the tracking"),
    replace(import_option("downscale"), default=4.0, help="shrink every frame by F before everything else"),
    Option("frames", str, None, "video frames A to B-1 (default: all the videos share)"),
    *GROUND_OPTIONS,
)


def _default(name: str):
    return next(o.default for o in CAPTURE_OPTIONS if o.name == name)


STEPS = ("import", "silhouettes", "keypoints", "start", "track", "export")


@dataclass
class CaptureResult:
    """Where a capture wrote its files and how long each step took (seconds; 0 for a step found done)."""

    out: Path
    files: dict[str, Path]
    seconds: dict[str, float] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)


def _same(path: Path, settings: dict) -> bool:
    """Whether ``path`` (a JSON record) holds exactly ``settings``."""
    try:
        return json.loads(path.read_text(encoding="utf-8")) == settings
    except (OSError, ValueError):
        return False


def capture(videos: Sequence[str | Path], calibration: str | Path, out: str | Path, *,
            views: Sequence[int] | str | None = None, prior: str = _default("prior"), seed: int = _default("seed"),
            particles: int = _default("particles"), downscale: float = _default("downscale"),
            frames: str | None = None, ground_std: float | None = None, root_height_std: float | None = None,
            overwrite: bool = False, on_step: Callable[[str, str], None] | None = None) -> CaptureResult:
    """Run the steps of the module docstring on ``videos`` (one per camera of ``calibration``, paired by sorted
    name) into the folder ``out``. ``views``: the cameras to use (indices into the calibration's, default all);
    ``prior``, ``seed``, ``particles`` and the likelihood's ground contact (``ground_std``, ``root_height_std``;
    None: on with one camera, off with more) go to ``track``; ``downscale`` and ``frames`` (``"A:B"``) to the
    import. ``on_step(step, line)`` hears one line per finished step. A rerun skips the steps whose settings
    are unchanged; a folder holding a capture of other videos or views is refused without ``overwrite``."""
    import tracker
    from data_tools.io.files import write_text_atomic
    from data_tools.vision.video import pair_videos, probe_video
    from tracker.app.plugins import prior_entry

    prior_entry(prior)  # an unknown prior is refused before any work
    given = {"views": views, "prior": prior, "particles": particles, "seed": seed, "downscale": downscale,
             "frames": frames, "ground_std": ground_std, "root_height_std": root_height_std}
    checked = {o.name: o.parse(given[o.name], "capture") for o in CAPTURE_OPTIONS}
    views, particles, seed, downscale = checked["views"], checked["particles"], checked["seed"], checked["downscale"]
    out = Path(out)
    videos = [Path(v) for v in videos]
    for v in videos:
        probe_video(v)  # every video readable before anything is written
    from data_tools.sequences.rig_formats import read_rig

    rig = read_rig(calibration)
    paired = pair_videos(rig.names, videos)
    chosen = list(range(len(rig))) if views is None else list(views)
    bad = [v for v in chosen if not 0 <= v < len(rig)]
    if bad or not chosen or len(set(chosen)) != len(chosen):
        raise InputError(f"views must be distinct camera indices 0..{len(rig) - 1}, got {chosen}", calibration)
    source = {"videos": [str(p.resolve()) for p in paired], "calibration": str(Path(calibration).resolve()),
              "views": chosen, "downscale": float(downscale), "frames": frames}
    record = out / "capture_source.json"
    if out.exists() and not out.is_dir():
        raise InputError("not a folder: give another --out", out)
    # (a folder holding only the record is a capture stopped or refused before its import: nothing to keep)
    if out.exists() and set(out.iterdir()) - {record} and not _same(record, source):
        if not overwrite:
            raise InputError("the folder holds other files or a capture of other videos, views or import "
                             "settings: give --overwrite to start it again, or another --out", out)
        if not record.is_file():  # --overwrite replaces a capture, never a folder this program did not write
            raise InputError("the folder holds files that no capture wrote: refusing to replace it, give another "
                             "--out", out)
        inside = [p for p in (*paired, Path(calibration)) if p.resolve().is_relative_to(out.resolve())]
        if inside:
            raise InputError(f"the input {inside[0]} lies inside the folder --overwrite would replace: give "
                             "another --out", out)
        import shutil

        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(record, json.dumps(source, indent=1, sort_keys=True))
    result = CaptureResult(out, {})
    say = on_step or (lambda step, line: None)

    ran: list[str] = []

    def step(name: str, done: bool, work: Callable[[], str], needs: tuple[str, ...] = ()) -> None:
        """Run ``work`` unless ``done`` and none of the steps it ``needs`` ran now (its files follow from theirs)."""
        if done and not set(needs) & set(ran):
            result.skipped.append(name)
            result.seconds[name] = 0.0
            say(name, "done before: kept")
            return
        ran.append(name)
        started = time.perf_counter()
        line = work()
        result.seconds[name] = time.perf_counter() - started
        say(name, f"{line} ({result.seconds[name]:.1f} s)")

    seq_dir = out / "sequence"
    mapping = {rig.names[v]: str(paired[v]) for v in chosen}

    def do_import() -> str:
        from data_tools.vision.video import import_videos

        imported = import_videos(calibration, paired, seq_dir, downscale=downscale, frames=frames, mapping=mapping)
        first = imported.rig[0]
        return (f"{len(imported.rig)} camera(s), {imported.stop - imported.start} frames of "
                f"{first.width}x{first.height} -> {seq_dir}")

    step("import", (seq_dir / "meta.json").is_file(), do_import)
    from data_tools.sequences.sequence import read_sequence

    seq = read_sequence(seq_dir)

    def do_masks() -> str:
        from tracker.app.preparation import write_silhouettes

        written = write_silhouettes(seq, overwrite=True)
        return f"{written.method} masks, the person {100 * float(np.mean(written.person_share)):.1f}% of each image"

    step("silhouettes", (seq_dir / "masks").is_dir(), do_masks, needs=("import",))

    def do_keypoints() -> str:
        from data_tools.vision.keypoints.readers import found_share
        from tracker.app.preparation import write_sequence_keypoints

        found = write_sequence_keypoints(seq_dir, overwrite=True)  # (replaced, whatever it was)
        share = found_share(found)  # of the keypoints the detector's layout has, as the keypoints command says
        return f"{found.source.get('detector')}: {100 * share:.0f}% of keypoints found"

    step("keypoints", (seq_dir / "keypoints" / "keypoints.npz").is_file(), do_keypoints, needs=("import",))
    seq = read_sequence(seq_dir)
    init_path = out / "init.npz"

    def do_start() -> str:
        from tracker.app.preparation import initialise_sequence

        start = initialise_sequence(seq_dir, init_path, evidence="keypoints", overwrite=True)
        return f"{start.lines[0].split(';')[0]}, {start.summary}"

    step("start", init_path.is_file(), do_start, needs=("keypoints",))
    seq = read_sequence(seq_dir)
    run_dir = out / "run"
    ground = {name: checked[name] for name in ("ground_std", "root_height_std")}
    # the version too: another version's tracking (its defaults, its shipped model) is not this one's
    track_settings = {"prior": prior, "seed": seed, "particles": particles, **ground, "version": tracker.__version__}
    track_record = out / "track_settings.json"

    def do_track() -> str:
        import shutil

        from tracker.app.api import track

        if run_dir.exists():
            shutil.rmtree(run_dir)
        init = np.load(init_path)["poses"]
        run = track(seq, prior, init=init, seed=seed, particles=particles, known_frames=len(init),
                    **{k: v for k, v in ground.items() if v is not None})
        run.save(run_dir)
        write_text_atomic(track_record, json.dumps(track_settings, sort_keys=True))
        return f"{prior}, {particles} particles, {run.seconds_per_frame:.3f} s per frame -> {run_dir}"

    step("track", (run_dir / "result.json").is_file() and _same(track_record, track_settings), do_track,
         needs=("silhouettes", "keypoints", "start"))

    def do_export() -> str:
        from data_tools.vision.keypoints.triangulate import (
            median_filter,
            triangulate_keypoints,
            write_keypoints_trc,
        )
        from tracker.app.exporting import export_poses
        from tracker.app.visualize import overlay_frames, write_video

        poses = np.load(run_dir / "estimates.npz")["poses"]
        fps = seq.fps or 60.0
        export_poses(seq, poses, bvh=out / "poses.bvh", trc=out / "poses.trc")
        written = ["poses.trc", "poses.bvh"]
        if seq.n_views >= 2:
            points = median_filter(triangulate_keypoints(seq.rig, seq.keypoints.points).points)
            write_keypoints_trc(out / "triangulated.trc", points, fps)
            written.append("triangulated.trc")
        write_video(out / "overlay.mp4", overlay_frames(seq, poses, list(range(seq.n_views))), fps)
        written.append("overlay.mp4")
        return ", ".join(written) + f" -> {out}"

    step("export", False, do_export)
    result.files = {name: out / name for name in ("poses.trc", "poses.bvh", "triangulated.trc", "overlay.mp4",
                                                  "init.npz", "run", "sequence") if (out / name).exists()}
    summary = {"settings": {**source, **track_settings}, "seconds": result.seconds, "skipped": result.skipped,
               "files": {k: str(v) for k, v in result.files.items()}}
    write_text_atomic(out / "result.json", json.dumps(summary, indent=1, sort_keys=True))
    return result
