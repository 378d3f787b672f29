"""A tracked run against another method's reconstruction (a TRC file): markers matched by a small named map,
one rigid alignment of the whole sequence, per-joint and mean distances.

The reference's keypoints are not this toolkit's markers: a 2-D detector's hip keypoint sits on the skin, not at
the hip joint centre; its neck is not the thorax point. Distances therefore hold a fixed offset per joint that
no tracking removes; they compare runs with each other better than they measure error.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from tracker.core.body import MARKER_NAMES
from tracker.core.errors import InputError

#: Our markers from the keypoints of Pose2Sim's and OpenPose-style (BODY_25, HALPE_26) TRC files: one name, or
#: several whose mean is taken. The pelvis is left out: the model's pelvis point lies about 80 mm above the
#: mean of its hip joints, so no keypoint pair stands for it.
POSE2SIM_MAP: dict[str, tuple[str, ...]] = {
    "thorax": ("Neck",), "head": ("Head",),
    "left_shoulder": ("LShoulder",), "left_elbow": ("LElbow",), "left_wrist": ("LWrist",),
    "right_shoulder": ("RShoulder",), "right_elbow": ("RElbow",), "right_wrist": ("RWrist",),
    "left_hip": ("LHip",), "left_knee": ("LKnee",), "left_ankle": ("LAnkle",),
    "right_hip": ("RHip",), "right_knee": ("RKnee",), "right_ankle": ("RAnkle",),
}


@dataclass
class ReferenceComparison:
    """Distances (mm) after one rigid alignment: ``per_joint`` (marker name -> mean over frames), ``mean`` (over
    joints and frames), ``per_frame`` (one per frame compared), the alignment (``rotation`` 3x3, ``translation``
    (3,), estimate -> reference), how many ``frames`` were compared and which (``compared``: the estimate's frame
    indices)."""

    per_joint: dict[str, float]
    mean: float
    per_frame: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    frames: int
    compared: np.ndarray

    def to_dict(self) -> dict:
        """The distances as JSON-ready numbers (``mean``, ``per_joint``, ``per_frame`` and ``frames``: the
        estimate's frame of each)."""
        return {"mean": self.mean, "per_joint": dict(self.per_joint),
                "per_frame": [float(d) for d in self.per_frame], "frames": [int(k) for k in self.compared]}

    def table(self) -> str:
        """A plain-text table: one row per joint, then the mean."""
        width = max(len(n) for n in self.per_joint)
        rows = [f"{'joint':<{width}}  distance (mm)"]
        rows += [f"{n:<{width}}  {d:8.1f}" for n, d in self.per_joint.items()]
        rows.append(f"{'mean':<{width}}  {self.mean:8.1f}   ({self.frames} frames, one rigid alignment)")
        return "\n".join(rows)


def mapped_reference(names: Sequence[str], points: np.ndarray,
                     mapping: Mapping[str, Sequence[str]] = POSE2SIM_MAP) -> tuple[list[str], np.ndarray]:
    """Our marker names that ``mapping`` finds in the reference, and their reference positions ``T x M x 3``."""
    index = {n: i for i, n in enumerate(names)}
    found, columns = [], []
    for marker in MARKER_NAMES:
        sources = mapping.get(marker, ())
        if sources and all(s in index for s in sources):
            found.append(marker)
            columns.append(points[:, [index[s] for s in sources]].mean(axis=1))
    if len(found) < 3:
        raise InputError(f"the reference names too few keypoints of the map ({', '.join(names[:8])}...): at least "
                         "3 of our markers are needed for an alignment")
    return found, np.stack(columns, axis=1)


def rigid_alignment(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``R`` and translation ``t`` minimising ``|R source + t - target|^2`` over all points ``(N, 3)``
    (Kabsch; no scaling, no reflection)."""
    ms, mt = source.mean(axis=0), target.mean(axis=0)
    u, _, vt = np.linalg.svd((source - ms).T @ (target - mt))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return R, mt - R @ ms


def compare_to_reference(markers: np.ndarray, ref_names: Sequence[str], ref_points: np.ndarray,
                         mapping: Mapping[str, Sequence[str]] = POSE2SIM_MAP,
                         offset: int = 0) -> ReferenceComparison:
    """Compare estimated markers ``T x 15 x 3`` (mm, our marker order) with reference keypoints
    ``T' x N x 3`` (mm): estimate frame ``k`` against reference frame ``k + offset``, as many frames as both
    have; frames where a mapped keypoint is missing (NaN) are left out of the alignment and the distances."""
    markers = np.asarray(markers, float)
    found, ref = mapped_reference(list(ref_names), np.asarray(ref_points, float), mapping)
    ref = ref[offset:]
    T = min(len(markers), len(ref))
    if T < 1:
        raise InputError(f"no frames in common: the estimate has {len(markers)}, the reference {len(ref_points)} "
                         f"from frame {offset}")
    est = markers[:T, [MARKER_NAMES.index(n) for n in found]]
    ref = ref[:T]
    ok = np.all(np.isfinite(ref), axis=(1, 2)) & np.all(np.isfinite(est), axis=(1, 2))
    if not ok.any():
        raise InputError("no frame where every mapped keypoint of the reference is present")
    R, t = rigid_alignment(est[ok].reshape(-1, 3), ref[ok].reshape(-1, 3))
    dist = np.linalg.norm(est[ok] @ R.T + t - ref[ok], axis=-1)  # frames x M
    return ReferenceComparison({n: float(d) for n, d in zip(found, dist.mean(axis=0))}, float(dist.mean()),
                               dist.mean(axis=1), R, t, int(ok.sum()), np.flatnonzero(ok))


def reference_offset(meta: Mapping) -> int:
    """The reference frame that a run's first frame is compared with unless told otherwise: the first video frame
    the sequence was imported from (``meta.json``'s ``first_video_frame``), else 0."""
    return int(meta.get("first_video_frame", 0))


def compare_to_trc(markers: np.ndarray, path: str | Path, offset: int = 0) -> ReferenceComparison:
    """:func:`compare_to_reference` of estimated markers ``T x 15 x 3`` (mm) against the TRC file ``path``
    (:func:`data_tools.motion.trc.read_trc`, keypoints mapped by :data:`POSE2SIM_MAP`); a problem is one
    :class:`InputError` naming the file."""
    from data_tools.motion.trc import read_trc

    ref = read_trc(path)
    try:
        return compare_to_reference(markers, ref.names, ref.points, offset=offset)
    except InputError as exc:
        raise InputError(exc.reason, exc.path or path) from None


def check_reference(path: str | Path, offset: int, frames: int) -> None:
    """Refuse, in one :class:`InputError` naming the file, a TRC reference that a run of ``frames`` frames
    compared from reference frame ``offset`` on could not be compared with: unreadable, too few keypoints of
    the map, no frame in that range, or none where every mapped keypoint is present."""
    from data_tools.motion.trc import read_trc

    ref = read_trc(path)
    try:
        _, points = mapped_reference(ref.names, ref.points)
    except InputError as exc:
        raise InputError(exc.reason, path) from None
    window = points[offset:offset + frames]
    if not len(window):
        raise InputError(f"no frames in common: the reference has {len(points)}, the run would start at its frame "
                         f"{offset}", path)
    if not np.all(np.isfinite(window), axis=(1, 2)).any():
        raise InputError(f"no frame from {offset} to {offset + len(window) - 1} where every mapped keypoint is "
                         "present", path)
