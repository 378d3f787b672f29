"""A 2-D keypoint detector's errors, simulated on synthetic sequences whose 3-D truth is known.

:func:`simulate_detections` projects the true keypoints ``T x K x 3`` (mm) into every view and spoils them as
a detector does (:class:`DetectorNoise`, every setting with its unit):

1. **noise**: each pixel coordinate moves by a Gaussian whose standard deviation is ``noise_mm`` on the
   person, converted to pixels per view and point by its depth (``f * noise_mm / depth``, ``f`` the view's
   focal length in pixels along that axis), so that the error is the same on the body at any resolution,
   and never below ``noise_floor_px`` pixels;
2. **left/right swaps**: in each frame and view, each group of
   :data:`tracker.core.keypoints.SWAP_GROUPS` (arms, legs, ears) is labelled the wrong way round with
   probability ``swap_rate``: the left points take the right side's (noisy) places and the other way;
3. **outliers**: each point, with probability ``outlier_rate``, is placed elsewhere: with probability
   ``outlier_at_keypoint`` at another keypoint's (noisy) place in that view (chosen uniformly among the
   others), otherwise uniformly in the person's bounding box in that view (the true keypoints' extent
   enlarged by ``box_margin`` of its width and height on every side, clipped to the image);
4. **confidences**: inliers (swapped points included: a detector is as sure of them) draw their confidence
   from ``Beta(*inlier_confidence)``, outliers from ``Beta(*outlier_confidence)``: by default mean 0.86 and
   standard deviation 0.10 against mean 0.40 and standard deviation 0.20, so a confidence threshold of 0.3
   keeps nearly all inliers and drops about a third of the outliers;
5. **misses**: each point is not found with probability ``miss_rate``, and a whole view in a frame (the
   person not detected at all) with probability ``view_miss_rate``; points whose final place lies outside
   the image (``x`` outside ``[-0.5, W - 0.5]`` or ``y`` outside ``[-0.5, H - 0.5]``) or that are behind the
   camera are dropped too. A point not found has NaN pixels and confidence 0 (the convention of
   :mod:`data_tools.sequences.keypoint_file`).

Points hidden behind the body are not modelled: a detector guesses them, with the same kinds of errors.

The defaults resemble a good detector (RTMPose, a recent OpenPose) on a person about 170 pixels tall in a
272 x 480 to 480 x 640 image: 25 mm of noise (2.5 pixels at 6 m with a 600-pixel focal length), 3 % outliers,
2 % swaps per group, 3 % missed points and 1 % missed views.

Every number is drawn from the generator passed in, all of them in one fixed order and shape whatever the
settings, so that the same seed gives the same detections, and two settings that differ in one rate share
every other draw.
"""
from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass

import numpy as np

from data_tools.sequences.keypoint_file import SequenceKeypoints
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError
from tracker.core.keypoints import KEYPOINTS, SWAP_GROUPS, keypoint_positions, swap_permutation

#: The ``detector`` name and ``version`` that :func:`simulate_sequence_keypoints` records.
DETECTOR = "simulated"
VERSION = "1"


@dataclass(frozen=True)
class DetectorNoise:
    """How a simulated detector errs (see the module): ``noise_mm`` (mm on the person, one standard deviation
    per pixel axis), ``noise_floor_px`` (pixels), ``outlier_rate``, ``outlier_at_keypoint``, ``swap_rate``
    (per frame, view and swap group), ``miss_rate`` (per point), ``view_miss_rate`` (per frame and view)
    (probabilities in [0, 1]), ``box_margin`` (a fraction of the person's image box on each side) and the
    Beta distributions ``(a, b)`` of inliers' and outliers' confidences."""

    noise_mm: float = 25.0
    noise_floor_px: float = 0.5
    outlier_rate: float = 0.03
    outlier_at_keypoint: float = 0.5
    box_margin: float = 0.25
    swap_rate: float = 0.02
    miss_rate: float = 0.03
    view_miss_rate: float = 0.01
    inlier_confidence: tuple[float, float] = (9.0, 1.5)
    outlier_confidence: tuple[float, float] = (2.0, 3.0)

    def __post_init__(self) -> None:
        for name in ("noise_mm", "noise_floor_px", "box_margin"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise InputError(f"detector noise: {name} must be a finite number >= 0, got {value!r}")
        for name in ("outlier_rate", "outlier_at_keypoint", "swap_rate", "miss_rate", "view_miss_rate"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise InputError(f"detector noise: {name} is a probability in [0, 1], got {value!r}")
        for name in ("inlier_confidence", "outlier_confidence"):
            value = getattr(self, name)
            if len(value) != 2 or not all(np.isfinite(v) and v > 0 for v in value):
                raise InputError(f"detector noise: {name} is a Beta distribution's (a, b), both > 0, got {value!r}")


@dataclass
class SimulatedDetections:
    """Simulated detections ``points`` ``T x V x K x 3`` (pixel x, y and confidence; NaN and 0 where not
    found) and what happened to each: ``swapped`` ``T x V x G`` (a swap group labelled the wrong way round),
    ``outliers`` ``T x V x K`` and ``dropped`` ``T x V x K`` (missed, in a missed view, outside the image or
    behind the camera), all bool."""

    points: np.ndarray
    swapped: np.ndarray
    outliers: np.ndarray
    dropped: np.ndarray


def simulate_detector(rig: CameraRig, keypoints_world: np.ndarray, rng: np.random.Generator,
                      noise: DetectorNoise = DetectorNoise()) -> SimulatedDetections:
    """The detections of the keypoints ``T x K x 3`` (mm, world) in the rig's ``V`` views, with ``noise``
    (the module says how), and what happened to each point."""
    X = np.asarray(keypoints_world, float)
    if X.ndim != 3 or X.shape[-1] != 3:
        raise InputError(f"keypoints must be T x K x 3 (mm), got shape {X.shape}")
    T, K = X.shape[:2]
    V, G = len(rig), len(SWAP_GROUPS)
    truth, depth = rig.project(X)  # T x V x K x 2, T x V x K
    size = np.array([[c.width, c.height] for c in rig.cameras], float)[:, None, :]  # V x 1 x 2

    # Every draw, in one order and shape whatever the settings.
    gauss = rng.standard_normal((T, V, K, 2))
    swap_draw = rng.random((T, V, G))
    outlier_draw = rng.random((T, V, K))
    kind_draw = rng.random((T, V, K))
    box_draw = rng.random((T, V, K, 2))
    other_draw = rng.integers(1, max(K, 2), size=(T, V, K))
    inlier_conf = rng.beta(*noise.inlier_confidence, size=(T, V, K))
    outlier_conf = rng.beta(*noise.outlier_confidence, size=(T, V, K))
    miss_draw = rng.random((T, V, K))
    view_miss_draw = rng.random((T, V))

    in_front = depth > 0
    sigma = rig.focal[:, None, :] * noise.noise_mm / np.where(in_front, depth, 1.0)[..., None]
    pixels = truth + np.maximum(sigma, noise.noise_floor_px) * gauss

    swapped = swap_draw < noise.swap_rate
    if K == len(KEYPOINTS):
        for g in range(G):
            order = swap_permutation((g,))
            pixels = np.where(swapped[:, :, g, None, None], pixels[:, :, order], pixels)
    elif swapped.any():
        raise InputError(f"left/right swaps need the {len(KEYPOINTS)} body keypoints, got {K} points")

    outliers = outlier_draw < noise.outlier_rate
    other = (np.arange(K) + other_draw) % K  # another keypoint, uniformly among the K - 1 others
    at_keypoint = np.take_along_axis(pixels, np.broadcast_to(other[..., None], pixels.shape), axis=2)
    seen_truth = np.where(in_front[..., None], truth, np.nan)
    with warnings.catch_warnings():  # a view that sees none of the person has no box: its outliers are dropped
        warnings.simplefilter("ignore", RuntimeWarning)
        low, high = np.nanmin(seen_truth, axis=2), np.nanmax(seen_truth, axis=2)  # T x V x 2
    margin = noise.box_margin * (high - low)
    low = np.clip(low - margin, -0.5, size[:, 0] - 0.5)
    high = np.clip(high + margin, -0.5, size[:, 0] - 0.5)
    in_box = low[:, :, None] + box_draw * (high - low)[:, :, None]
    elsewhere = np.where((kind_draw < noise.outlier_at_keypoint)[..., None], at_keypoint, in_box)
    pixels = np.where(outliers[..., None], elsewhere, pixels)
    confidence = np.where(outliers, outlier_conf, inlier_conf)

    inside = ((pixels >= -0.5) & (pixels <= size - 0.5)).all(axis=-1) & in_front & np.isfinite(pixels).all(-1)
    dropped = ~inside | (miss_draw < noise.miss_rate) | (view_miss_draw < noise.view_miss_rate)[..., None]
    points = np.concatenate([pixels, confidence[..., None]], axis=-1)
    points[dropped] = (np.nan, np.nan, 0.0)
    return SimulatedDetections(points, swapped, outliers & ~dropped, dropped)


def simulate_detections(rig: CameraRig, keypoints_world: np.ndarray, rng: np.random.Generator,
                        noise: DetectorNoise = DetectorNoise()) -> np.ndarray:
    """Detections ``T x V x K x 3`` (pixel x, y, confidence; NaN and 0 where not found) of the keypoints
    ``T x K x 3`` (mm, world) in the rig's ``V`` views, as a detector with ``noise`` would give them
    (:func:`simulate_detector`)."""
    return simulate_detector(rig, keypoints_world, rng, noise).points


def simulate_sequence_keypoints(seq, rng: np.random.Generator,
                                noise: DetectorNoise = DetectorNoise()) -> SequenceKeypoints:
    """Simulated keypoints of a sequence with ground-truth poses (``seq``: a
    :class:`~data_tools.sequences.sequence.Sequence`, or anything with its ``rig``, ``model`` and ``groundtruth``): the
    body model's keypoints at the true poses, detected with ``noise``. The ``source`` records the detector
    ``"simulated"``, the ``layout`` ``"keypoints"`` (the body keypoints themselves) and every noise setting."""
    if getattr(seq, "groundtruth", None) is None:
        raise InputError("simulated keypoints need the sequence's ground-truth poses; this one has none",
                         getattr(seq, "root", None))
    world = keypoint_positions(seq.model, np.asarray(seq.groundtruth.poses, float))
    points = simulate_detections(seq.rig, world, rng, noise)
    source = {"detector": DETECTOR, "version": VERSION, "layout": "keypoints",
              "noise": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(noise).items()}}
    return SequenceKeypoints(points, tuple(seq.rig.names), source)
