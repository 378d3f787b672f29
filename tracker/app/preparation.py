"""A sequence folder of real video made trackable, one step at a time: the person's silhouettes, the 2-D
keypoints, and a start (the body's size and first poses).

Each step is one call that reads the sequence, refuses what it cannot do in one line, writes its files whole and
returns what it did; ``pose-tracker silhouettes``, ``keypoints`` and ``initialise`` are these calls, and
``pose-tracker capture`` (:mod:`tracker.app.capture`) runs them in turn.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from tracker.core.errors import InputError

log = logging.getLogger(__name__)

__all__ = ["Silhouettes", "write_silhouettes", "write_sequence_keypoints", "Start", "initialise_sequence"]


@dataclass(frozen=True)
class Silhouettes:
    """Silhouettes written: by ``method``, the mean share of each camera's image that is person."""

    root: Path
    method: str
    cameras: tuple[str, ...]
    frames: int
    person_share: tuple[float, ...]


def write_silhouettes(sequence, method: str | None = None, *, overwrite: bool = False,
                      overwrite_flag: str = "overwrite=True") -> Silhouettes:
    """Write ``masks/<camera>/NNNNNN.png`` into ``sequence`` (a folder of this toolkit's layout, or a loaded
    :class:`~data_tools.sequences.sequence.Sequence`) by ``method`` (:mod:`tracker.app.silhouettes`; default
    :func:`~tracker.app.silhouettes.default_method`). A sequence that has masks is refused unless ``overwrite``
    (``overwrite_flag``: how the refusal says so)."""
    from data_tools.sequences.sequence import OWN, read_sequence
    from tracker.app.silhouettes import default_method, write_sequence_masks

    seq = read_sequence(sequence) if isinstance(sequence, (str, Path)) else sequence
    if seq.layout != OWN:
        raise InputError("silhouettes are written into sequence folders of this toolkit's layout only", seq.root)
    if seq.mask_paths is not None and not overwrite:
        raise InputError(f"the sequence already has masks/ (pass {overwrite_flag} to replace them)", seq.root)
    method = method or default_method(seq)  # (runs the person model: after the refusals)
    shares = write_sequence_masks(seq, method)
    return Silhouettes(seq.root, method, tuple(seq.rig.names), seq.n_frames, tuple(float(f) for f in shares))


def write_sequence_keypoints(sequence: str | Path, *, sources: Sequence[str] | None = None,
                             layout: str | None = None, overwrite: bool = False,
                             progress: Callable[[int, int], None] | None = None,
                             overwrite_flag: str = "overwrite=True"):
    """Write ``keypoints/keypoints.npz`` into ``sequence`` (a folder) and return the keypoints: read from another
    tool's files (``sources``: one per camera in the sequence's camera order, or ``CAMERA=PATH`` each; ``layout``
    their keypoint layout where the point count does not tell it) or, without ``sources``, detected in the
    sequence's images (``progress(done, total)`` over the images). A sequence that has keypoints is refused
    unless ``overwrite`` (``overwrite_flag``: how the refusal says so)."""
    from data_tools.sequences.keypoint_file import keypoints_path, write_keypoints

    path = keypoints_path(sequence)
    if path.exists() and not overwrite:
        raise InputError(f"the sequence already has keypoints (pass {overwrite_flag} to replace them)", path)
    if sources:
        from data_tools.vision.keypoints.readers import import_keypoints

        return import_keypoints(sequence, sources, layout)
    if layout:
        raise InputError("--layout names the layout of files read with --from; the detector knows its own")
    try:
        from data_tools.vision.keypoints.detect import detect_sequence_keypoints
    except ModuleNotFoundError as exc:
        if exc.name != "data_tools.vision.keypoints.detect":
            raise
        raise InputError("this installation has no keypoint detector: read keypoints from another tool with "
                         "--from PATH ...") from None
    from data_tools.sequences.sequence import read_sequence
    from data_tools.vision.keypoints.readers import check_keypoint_layout

    seq = read_sequence(sequence, keypoints=False)  # the file this replaces may be broken
    check_keypoint_layout(seq)
    keypoints = detect_sequence_keypoints(seq, progress=progress)
    write_keypoints(seq.root, keypoints)
    return keypoints


@dataclass(frozen=True)
class Start:
    """A sequence's start, written: the first ``poses`` ``F x D`` (in ``out``) of the body whose ``shape`` went
    into the sequence's ``meta.json`` (``meta_file``); ``evidence`` what they were fitted to, ``lines`` what the
    fit found, in words (``summary`` the one that says how well)."""

    out: Path
    meta_file: Path
    poses: np.ndarray
    shape: object
    evidence: str
    summary: str
    lines: tuple[str, ...] = ()


def initialise_sequence(sequence: str | Path, out: str | Path, *, evidence: str | None = None,
                        near: str | Path | None = None, proportions: str = "scale", frames: int = 2, seed: int = 0,
                        overwrite: bool = False, overwrite_flag: str = "overwrite=True") -> Start:
    """Fit the body's size and first ``frames`` poses of ``sequence`` (a folder of this toolkit's layout), write
    the body shape into its ``meta.json`` (which tracking then uses) and the poses to ``out`` (``.npz`` with
    ``poses``, for ``track(init=...)``).

    ``evidence``: ``"keypoints"`` (the default where the sequence has keypoints: the body measured from the
    keypoints triangulated over the views, the poses fitted to them; :mod:`tracker.app.keypoint_start`) or
    ``"silhouettes"`` (the default otherwise: the likelihood's search of :mod:`tracker.app.initialise`, around
    the poses file ``near`` where given, with ``proportions`` ``"scale"`` (the default adult's, scaled) or
    ``"landmarks"`` (the person's own, from BlazePose's landmarks)). An existing ``out`` is refused unless
    ``overwrite`` (``overwrite_flag``: how the refusal says so)."""
    from data_tools.io.files import check_output_file
    from data_tools.sequences.sequence import OWN, read_sequence, write_meta

    out = check_output_file(out, "the poses file", (".npz",), new=not overwrite, overwrite_flag=overwrite_flag)
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < 1:
        raise InputError(f"frames must be an integer of at least 1, got {frames!r}")
    if evidence not in (None, "keypoints", "silhouettes"):
        raise InputError(f"evidence must be keypoints or silhouettes, got {evidence!r}")
    if proportions not in ("scale", "landmarks"):
        raise InputError(f"proportions must be scale or landmarks, got {proportions!r}")
    seq = read_sequence(sequence)
    if seq.layout != OWN:
        raise InputError("initialise writes the fitted shape into meta.json: this toolkit's layout only",
                         seq.root)
    evidence = evidence or ("keypoints" if seq.keypoints is not None else "silhouettes")
    if evidence == "keypoints":
        if near is not None or proportions != "scale":
            raise InputError("near and proportions apply to a start from silhouettes (evidence silhouettes)")
        from tracker.app.keypoint_start import initialise_from_keypoints

        fitted = initialise_from_keypoints(seq, known_frames=frames)
        lengths = ", ".join(f"{k} {v:.0f}" for k, v in fitted.lengths.items())
        start = Start(out, seq.root / "meta.json", fitted.poses, fitted.shape, evidence,
                      f"first poses fitted to the keypoints (cost {fitted.cost:.1f})",
                      (f"standing height {fitted.height:.0f} mm" + (f"; measured {lengths} mm" if lengths else ""),))
    else:
        start = _start_from_silhouettes(seq, out, near, proportions, frames, seed)
    meta = dict(seq.meta)
    meta["body_shape"] = start.shape.to_dict()
    write_meta(seq.root, meta)
    write_poses(out, start.poses)
    return start


def _start_from_silhouettes(seq, out: Path, near, proportions: str, frames: int, seed: int) -> Start:
    """The start :func:`tracker.app.initialise.initialise` finds on the first frame's silhouettes."""
    from data_tools.sequences.estimates import read_poses_file
    from tracker.app.initialise import initialise, limb_lengths

    near_pose = None if near is None else read_poses_file(near, "--near", seq.model)[0]
    shape, lines = None, []
    if proportions == "landmarks":
        from data_tools.vision.landmarks import measure, sequence_landmarks, shape_from_landmarks

        measured = measure(seq.rig, sequence_landmarks(seq), seq.root)
        shape = shape_from_landmarks(measured.lengths, seq.root)
        lines.append(f"landmarks of {len(measured.points)} frames, reprojection error "
                     f"{np.nanmedian(measured.errors):.1f} pixels (median): "
                     + ", ".join(f"{k} {v:.0f}" for k, v in measured.lengths.items()) + " mm")
    found = initialise(seq, 0, near=near_pose, seed=seed, shape=shape)
    lengths = ", ".join(f"{k} {v:.0f}" for k, v in limb_lengths(found.model, found.pose).items())
    lines.append(f"stance {found.stance}, scale {found.scale:g}: standing height {found.height:.0f} mm; {lengths} mm")
    return Start(out, seq.root / "meta.json", np.tile(found.pose, (frames, 1)), found.shape, "silhouettes",
                 f"first pose (log-likelihood {found.score:.1f})", tuple(lines))


def write_poses(path: str | Path, poses: np.ndarray) -> None:
    """``poses`` ``F x D`` written to ``path`` (.npz, ``poses``) whole, or ``path`` left as it was."""
    from data_tools.io.files import atomic_path

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, poses=poses)
