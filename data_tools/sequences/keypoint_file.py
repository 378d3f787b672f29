"""A sequence's 2-D keypoints on disk: ``seq/keypoints/keypoints.npz``, written once per sequence.

Arrays of the file:

``points``   ``T x V x K x 3`` float: pixel ``(x, y)`` (the pixel-centre convention of the sequence's images)
             and a confidence in [0, 1] per frame, view (the sequence's cameras, in ``cameras.json`` order) and
             keypoint (:data:`tracker.core.keypoints.KEYPOINTS` order); a keypoint not found has confidence 0
             and NaN pixels.
``cameras``  ``(V,)`` the camera names the views are.
``source``   a JSON text: ``detector`` (its name), ``version``, ``layout`` (the layout the points were mapped
             from) and whatever else the producer records (settings, the files read).

:func:`write_keypoints` writes the whole file at once (or leaves the one there as it was);
:func:`read_keypoints` checks it against the sequence.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from data_tools.io.checks import load_npz
from data_tools.io.files import atomic_path
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINTS

#: Where a sequence keeps its keypoints, relative to its folder.
KEYPOINTS_FILE = Path("keypoints") / "keypoints.npz"


@dataclass
class SequenceKeypoints:
    """A sequence's keypoints: ``points`` ``T x V x K x 3`` (see the module), the ``cameras`` they are in and
    their ``source`` (``detector``, ``version``, ``layout``, ...)."""

    points: np.ndarray
    cameras: tuple[str, ...]
    source: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.points = np.array(self.points, dtype=float)  # a copy: points not found are set below
        self.cameras = tuple(str(c) for c in self.cameras)
        if self.points.ndim != 4 or self.points.shape[2:] != (len(KEYPOINTS), 3):
            raise InputError(f"keypoints must be T x V x {len(KEYPOINTS)} x 3, got {self.points.shape}")
        if self.points.shape[1] != len(self.cameras):
            raise InputError(f"keypoints have {self.points.shape[1]} views but {len(self.cameras)} camera names")
        conf = self.points[..., 2]
        bad = ~np.isfinite(conf) | (conf < 0) | (conf > 1)
        if bad.any():
            raise InputError("keypoint confidences must lie in [0, 1]")
        missing = (conf == 0) | ~np.isfinite(self.points[..., :2]).all(axis=-1)
        self.points[missing] = (np.nan, np.nan, 0.0)

    @property
    def n_frames(self) -> int:
        return self.points.shape[0]

    @property
    def confidence(self) -> np.ndarray:
        """Confidences ``T x V x K`` (0 where not found)."""
        return self.points[..., 2]


def keypoints_path(seq_root: str | Path) -> Path:
    return Path(seq_root) / KEYPOINTS_FILE


def write_keypoints(seq_root: str | Path, keypoints: SequenceKeypoints) -> Path:
    """Write ``keypoints`` to ``seq_root/keypoints/keypoints.npz`` in one piece; returns the path."""
    path = keypoints_path(seq_root)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, points=keypoints.points, cameras=np.array(keypoints.cameras),
                                source=np.array(json.dumps(keypoints.source, sort_keys=True)))
    return path


def read_keypoints(seq_root: str | Path, cameras: tuple[str, ...] | list[str] | None = None,
                   n_frames: int | None = None) -> SequenceKeypoints | None:
    """The keypoints of the sequence in ``seq_root`` (None when it has none), checked against its camera names
    and frame count where given: a mismatch is an :class:`InputError` naming the file."""
    path = keypoints_path(seq_root)
    if not path.exists():
        return None
    arrays = load_npz(path, "the keypoints file", ("points", "cameras", "source"))
    try:
        source = json.loads(str(arrays["source"]))
    except ValueError:
        raise InputError("the keypoints file's source is not JSON", path) from None
    if not isinstance(source, dict):
        raise InputError("the keypoints file's source is not a JSON object", path)
    try:
        out = SequenceKeypoints(arrays["points"], tuple(np.atleast_1d(arrays["cameras"]).tolist()), source)
    except InputError as exc:
        raise InputError(exc.reason, path) from None
    if cameras is not None and tuple(cameras) != out.cameras:
        raise InputError(f"keypoints are of cameras {', '.join(out.cameras)} but the sequence has "
                         f"{', '.join(cameras)}", path)
    if n_frames is not None and out.n_frames != n_frames:
        raise InputError(f"keypoints have {out.n_frames} frames but the sequence has {n_frames}", path)
    return out
