"""Synthetic multi-view sequences: real mocap, retargeted, rendered into a calibrated rig (``python -m tracker synth``).

The clip is retargeted to the 15-cone model at the requested rate, the chosen
frames are cut out, and the walk is moved so that the whole clip's ground-plane
path is centred on the capture area (the shift is recorded in ``meta.json``). The
person is rendered with :mod:`data_tools.synthesis.render` (a mesh that differs from the
tracker's model) over a cluttered room, and the sequence is written in the
project's layout (:mod:`data_tools.sequences.sequence`).
"""
from __future__ import annotations

import os
import shutil

from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from data_tools.io.files import check_output_folder, follow_umask, fresh_beside, writing
from data_tools.motion.retarget import RetargetResult
from data_tools.sequences.sequence import frame_path, write_groundtruth, write_image, write_sequence_header
from data_tools.synthesis.render import compose, make_room, person_mesh, render_background, render_person
from tracker.core.kinematics import standing_height
from tracker.core.cameras import CameraRig, default_rig
from tracker.core.rotations import continuous_exp_maps, elementary_rotation, exp_map_to_matrix, matrix_to_exp_map
from tracker.core.errors import InputError
from data_tools.synthesis.synth_settings import SynthConfig, synth_option  # noqa: F401  (the settings, re-exported)


def turned(result: RetargetResult, degrees: float) -> RetargetResult:
    """``result`` turned by ``degrees`` about the world's vertical axis through the origin: the root's ground
    position and orientation and every marker. The body's motion is unchanged; only the direction it moves in
    (and faces) is. Root orientations stay continuous exp maps."""
    degrees = synth_option("turn").parse(degrees, "turned")
    if degrees == 0:
        return result
    Rz = elementary_rotation("z", np.radians(degrees))
    poses = result.poses.copy()
    poses[:, :2] = poses[:, :2] @ Rz[:2, :2].T
    poses[:, 3:6] = continuous_exp_maps(matrix_to_exp_map(Rz @ exp_map_to_matrix(poses[:, 3:6])))

    def turn_points(points: np.ndarray) -> np.ndarray:
        return points @ Rz.T

    return replace(result, poses=poses, markers=turn_points(result.markers),
                   model_markers=turn_points(result.model_markers))


def select_frames(result: RetargetResult, start: int, frames: int | None, source: str) -> slice:
    total = len(result.poses)
    if start < 0:
        raise InputError(f"--start must be >= 0, got {start}")
    if frames is not None and frames < 1:
        raise InputError(f"--frames must be >= 1, got {frames}")
    if start >= total:
        raise InputError(f"--start {start} is past the end of the clip ({total} frames at {result.fps:g} fps)", source)
    stop = total if frames is None else start + frames
    if stop > total:
        raise InputError(f"--start {start} --frames {frames} runs past the end of the clip ({total} frames at "
                         f"{result.fps:g} fps)", source)
    return slice(start, stop)


@dataclass
class SynthOutput:
    root: Path
    n_frames: int
    shift_mm: np.ndarray
    render_seconds: float
    masks: list[list[np.ndarray]] | None = None


def synthesize(result: RetargetResult, out: str | Path, settings: SynthConfig, source: str = "",
               rig: CameraRig | None = None, keep_masks: bool = False,
               progress: Callable | None = None, overwrite: bool = False) -> SynthOutput:
    """Render ``result`` (a retargeted clip) into a sequence folder ``out``.

    The folder is rendered under a temporary name beside ``out`` and renamed when complete, so a failure or
    Ctrl-C leaves nothing half-written. A non-empty ``out`` is refused unless ``overwrite`` (then it is
    replaced whole once the new sequence is complete). ``progress``, if given, wraps the frame iterator
    (e.g. ``tqdm``). ``keep_masks`` returns the renderer's exact person masks (``[frame][view]``) for testing
    the observation pipeline.
    """
    final = check_output_folder(out, empty=not overwrite, replaceable=("cameras.json", "meta.json"))
    with fresh_beside(final, ".tmp", directory=True) as tmp, \
            writing(final, "an earlier sequence there is kept" if final.exists() else ""):
        output = _render(result, tmp, settings, source, rig, keep_masks, progress)
        follow_umask(tmp, directory=True)
        if final.exists():
            shutil.rmtree(final)
        os.replace(tmp, final)
    output.root = final
    return output


def _render(result: RetargetResult, out: Path, settings: SynthConfig, source: str, rig: CameraRig | None,
            keep_masks: bool, progress: Callable | None) -> SynthOutput:
    import time

    s = settings
    rig = rig or default_rig(s.views, s.width, s.height)
    s.check_missing_camera(len(rig))
    result = turned(result, s.turn)
    span = select_frames(result, s.start, s.frames, source)
    poses = result.poses[span].copy()
    markers = result.markers[span].copy()
    path_xy = result.poses[:, :2]  # the whole clip, so a cut-out keeps its place in the room
    shift = (path_xy.min(axis=0) + path_xy.max(axis=0)) / 2.0
    poses[:, :2] -= shift
    markers[..., :2] -= shift
    rng = np.random.default_rng(s.seed)
    room = make_room(rng, rig, s.occluder)
    person = person_mesh(result.model, rng)
    plates = [render_background(cam, room) for cam in rig.cameras]
    depths = [d for _, d in plates]
    root = Path(out)
    n = len(poses)
    meta = {
        "source": source, "subject_stature_mm": round(standing_height(result.model), 1), "fps": result.fps,
        "frames": n, "start_frame": s.start, "body_shape": result.model.shape.to_dict(),
        "ground_plane_shift_mm": [float(x) for x in shift], "generator": "data_tools.synthesis.synth",
        "settings": asdict(s), "render_width_factors": [round(float(f), 4) for f in person.width_factors],
        "retarget_residual_mm": round(result.mean_residual, 3),
    }
    write_sequence_header(root, rig, meta)
    for v, cam in enumerate(rig.cameras):
        plate = plates[v][0]
        dead = v == s.missing_camera
        img = np.zeros(plate.shape, np.uint8) if dead else compose(plate, _no_person(plate), 1.0, s.noise, rng)
        write_image(root / "background" / f"{cam.name}.png", img)
    masks = [] if keep_masks else None
    t0 = time.perf_counter()
    frames = range(n) if progress is None else progress(range(n))
    for k in frames:
        gain = 1.0 + s.lighting_change * (k / max(n - 1, 1))
        views = render_person(person, result.model, poses[k], rig, depths)
        for v, cam in enumerate(rig.cameras):
            if v == s.missing_camera:
                img = np.zeros((cam.height, cam.width, 3), np.uint8)
            else:
                img = compose(plates[v][0], views[v], gain, s.noise, rng)
            write_image(frame_path(root, cam.name, k), img)
        if masks is not None:
            masks.append([r.mask for r in views])
    seconds = time.perf_counter() - t0
    write_groundtruth(root, poses, markers, result.fps)
    return SynthOutput(root=root, n_frames=n, shift_mm=shift, render_seconds=seconds, masks=masks)


def _no_person(plate: np.ndarray):
    from data_tools.synthesis.render import PersonRender

    return PersonRender(np.zeros_like(plate), np.zeros(plate.shape[:2], bool))
