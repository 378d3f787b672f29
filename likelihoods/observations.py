"""Image observations: foreground silhouettes by background subtraction, and edge maps.

The same pipeline runs on the synthetic frames and on real footage (the
bodytrack greyscale images with their provided masks). Images are ``H x W``
grey or ``H x W x 3`` RGB uint8; outputs are ``H x W`` float32 maps in [0, 1].

Silhouette (:func:`silhouette`)
    1. Optionally both image and background plate are blurred (Gaussian,
       ``blur_sigma`` px; off by default: at the scale of a 170-pixel person a
       blur moves the boundary by a pixel, which costs more than noise does).
    2. Optional global gain compensation: the median ratio image/background is
       taken as a change of illumination and applied to the plate.
    3. A pixel is foreground where its colour distance to the plate (Euclidean
       over the channels, grey levels) exceeds
       ``max(diff_threshold, noise_factor * sigma)``; ``sigma``, the per-pixel
       noise of the difference, is estimated robustly from the median distance
       (most pixels are background), so the threshold follows the sensor noise.
       The distances of the whole image are compared in one compiled pass
       (squared, against the squared threshold) that writes only the mask.
    4. Clean-up: opening with a disc of radius ``open_radius`` (removes specks),
       closing with radius ``close_radius`` (fills cracks), then connected
       components smaller than ``min_area`` pixels are dropped.

Edge map (:func:`edge_map`)
    1. Gradient magnitude of the grey image blurred by ``edge_blur_sigma`` px
       (Sobel, in grey levels per pixel).
    2. Threshold at ``edge_threshold`` -> binary edge pixels; optionally only
       those within ``foreground_margin`` px of the silhouette are kept (a
       cluttered background has many edges the person cannot explain).
    3. Smoothing that falls off around edges: ``exp(-d^2 / (2 edge_sigma^2))``
       with ``d`` the distance (px) to the nearest edge pixel, so the map is 1
       on an edge and decays smoothly to 0 away from it (Deutscher & Reid's
       smoothed edge map; Taylor 2009, Sec. 6.3.3).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from tracker.core.workers import share


@dataclass(frozen=True)
class ObservationConfig:
    """Parameters of the observation pipeline (pixels and 8-bit grey levels)."""

    blur_sigma: float = 0.0
    diff_threshold: float = 10.0
    noise_factor: float = 3.0
    compensate_gain: bool = True
    open_radius: int = 1
    close_radius: int = 1
    min_area: int = 40
    edge_blur_sigma: float = 1.0
    edge_threshold: float = 10.0
    edge_sigma: float = 3.0
    foreground_margin: int | None = 15


DEFAULT_OBSERVATION = ObservationConfig()


def _disc(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    f = img.astype(np.float32)
    return cv2.GaussianBlur(f, (0, 0), sigma) if sigma > 0 else f


def _grey(img: np.ndarray) -> np.ndarray:
    return img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)


def clean_mask(mask: np.ndarray, config: ObservationConfig = DEFAULT_OBSERVATION) -> np.ndarray:
    """Morphological clean-up of a bool ``H x W`` mask: open, close, drop small components."""
    m = mask.view(np.uint8) if mask.dtype == bool else mask.astype(np.uint8)
    if config.open_radius > 0:
        m = cv2.morphologyEx(m, cv2.MORPH_OPEN, _disc(config.open_radius))
    if config.close_radius > 0:
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, _disc(config.close_radius))
    rows, cols = _box(m, 0)  # components are labelled within the mask's bounding box only
    if config.min_area > 1 and rows.stop > rows.start:
        n, labels, stats, _ = cv2.connectedComponentsWithStats(m[rows, cols], connectivity=8)
        keep = np.zeros(n, bool)
        keep[1:] = stats[1:, cv2.CC_STAT_AREA] >= config.min_area
        if not keep[1:].all():  # (when every component is large enough the mask stays as it is)
            out = np.zeros(m.shape, bool)
            out[rows, cols] = keep[labels]
            return out
    return m.astype(bool)


@dataclass(frozen=True)
class BackgroundPlate:
    """A background plate with what :func:`silhouette` derives from it once per sequence and view.

    ``image``: the plate as given (``H x W x 3`` or ``H x W`` uint8); ``values``: ``image`` itself (contiguous),
    or float32 blurred by ``blur_sigma``; ``grey_sample``: the grey levels (float32) of every 4th row and column
    that exceed 20, ``sample_valid`` (bool, on the 4th rows and columns) says which: the denominators of the gain
    statistic.
    """

    image: np.ndarray
    blur_sigma: float
    values: np.ndarray
    sample_valid: np.ndarray
    grey_sample: np.ndarray

    @classmethod
    def of(cls, background: np.ndarray, config: ObservationConfig = DEFAULT_OBSERVATION) -> "BackgroundPlate":
        blurred = config.blur_sigma > 0
        values = _blur(background, config.blur_sigma) if blurred else np.ascontiguousarray(background)
        grey = _grey_float(values[::4, ::4].astype(np.float32))
        valid = grey > 20.0
        return cls(background, config.blur_sigma, values, valid, grey[valid])


def silhouette(image: np.ndarray, background: np.ndarray | BackgroundPlate,
               config: ObservationConfig = DEFAULT_OBSERVATION) -> np.ndarray:
    """Foreground mask (bool ``H x W``) of ``image`` against its background plate (same shape, uint8; or the
    plate prepared once by :meth:`BackgroundPlate.of`)."""
    plate = background if isinstance(background, BackgroundPlate) else BackgroundPlate.of(background, config)
    if plate.blur_sigma != config.blur_sigma:
        plate = BackgroundPlate.of(plate.image, config)
    if image.shape != plate.image.shape:
        raise ValueError(f"image {image.shape} and background {plate.image.shape} differ in shape")
    # The image as it is (uint8) unless blurred: the compiled pass converts each value as it reads it.
    img = _blur(image, config.blur_sigma) if config.blur_sigma > 0 else image
    gain = 1.0
    # Robust statistics (medians) are taken on every 4th row and column: 1/16 of the pixels is plenty.
    sample = img[::4, ::4].astype(np.float32)
    if config.compensate_gain and len(plate.grey_sample) > 100:
        gain = float(np.median(_grey_float(sample)[plate.sample_valid] / plate.grey_sample))
    diff = np.abs(sample - plate.values[::4, ::4] * np.float32(gain))
    if diff.ndim == 3:
        dist = np.sqrt(_channel_sum(np.square(diff)))
        chi_median = 1.5382  # median of a chi distribution with 3 degrees of freedom
    else:
        dist = diff
        chi_median = 0.6745  # median of |N(0, 1)|
    sigma = float(np.median(dist)) / chi_median
    threshold = max(config.diff_threshold, config.noise_factor * sigma)
    mask = np.empty(image.shape[:2], bool)
    _beyond(np.ascontiguousarray(img).reshape(-1), plate.values.reshape(-1),  # (the plate made contiguous once)
            img.shape[2] if img.ndim == 3 else 1, np.float32(gain), squared_threshold(threshold), mask.reshape(-1))
    return clean_mask(mask, config)


def squared_threshold(threshold: float) -> np.float32:
    """The largest float32 ``s`` whose float32 square root is at most ``float32(threshold)``: a squared distance
    exceeds it exactly when its float32 square root exceeds the threshold, so that comparing squares (no square
    root per pixel) marks the same pixels as comparing distances, ties included."""
    t = np.float32(threshold)
    s = np.float32(t * t)
    while s > 0 and np.sqrt(s) > t:
        s = np.nextafter(s, np.float32(0.0))
    while np.sqrt(np.nextafter(s, np.float32(np.inf))) <= t:
        s = np.nextafter(s, np.float32(np.inf))
    return s


@njit(cache=True, nogil=True)
def _beyond(image, plate, channels, gain, threshold_squared, out):
    """``out[i] = True`` where the squared colour distance of pixel ``i`` of ``image`` to ``gain`` times ``plate``
    exceeds ``threshold_squared`` (``image`` and ``plate`` flat, ``channels`` values per pixel, uint8 or float32;
    ``out`` flat bool): float32 throughout, without the GIL. Three channels are spelled out so that the loop
    compiles to vector instructions (7x faster than a loop over the channels)."""
    if channels == 3:
        for i in range(out.size):
            d0 = np.float32(image[3 * i]) - np.float32(plate[3 * i]) * gain
            d1 = np.float32(image[3 * i + 1]) - np.float32(plate[3 * i + 1]) * gain
            d2 = np.float32(image[3 * i + 2]) - np.float32(plate[3 * i + 2]) * gain
            out[i] = d0 * d0 + d1 * d1 + d2 * d2 > threshold_squared
    else:
        for i in range(out.size):
            total = np.float32(0.0)
            for c in range(channels):
                d = np.float32(image[channels * i + c]) - np.float32(plate[channels * i + c]) * gain
                total += d * d
            out[i] = total > threshold_squared


def _channel_sum(img: np.ndarray) -> np.ndarray:
    """The sum over the channels of a float ``H x W x C`` array (as ``sum(axis=2)`` adds them, in order; several
    times faster for few channels). A uint8 array would wrap around: callers convert first."""
    total = img[..., 0].copy()
    for c in range(1, img.shape[2]):
        total += img[..., c]
    return total


def _grey_float(img: np.ndarray) -> np.ndarray:
    """The mean over the channels of a float ``H x W x C`` image (``H x W`` as it is)."""
    return img if img.ndim == 2 else _channel_sum(img) / np.float32(img.shape[2])


def gradient_magnitude(image: np.ndarray, blur_sigma: float = 1.0) -> np.ndarray:
    """Gradient magnitude ``H x W`` float32 of the blurred grey image, grey levels per pixel."""
    g = _blur(_grey(image), blur_sigma)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    return cv2.magnitude(gx, gy)


#: Distance (in units of ``edge_sigma``) beyond which the smoothed edge map is below 2^-26, so that its cost
#: ``(1 - edge)^2`` is exactly 1 in float32; the map is only computed within this reach of an edge.
EDGE_REACH = 6.2


def _box(mask: np.ndarray, grow: int) -> tuple[slice, slice]:
    """Rows and columns of the bounding box of ``mask`` (uint8 ``H x W``) grown by ``grow`` pixels (empty
    slices for an empty mask)."""
    x, y, w, h = cv2.boundingRect(mask)
    H, W = mask.shape
    return slice(max(y - grow, 0), min(y + h + grow, H)), slice(max(x - grow, 0), min(x + w + grow, W))


def edge_map(image: np.ndarray, foreground: np.ndarray | None = None,
             config: ObservationConfig = DEFAULT_OBSERVATION) -> np.ndarray:
    """Smoothed edge map ``H x W`` float32 in [0, 1] (1 on an edge), see the module docstring.

    With a foreground mask only the box around it that edges near the person can reach (the margin plus
    ``EDGE_REACH`` edge widths) is computed: outside it the map is below 2^-26 and set to 0.
    """
    H, W = image.shape[:2]
    out = np.zeros((H, W), np.float32)
    restrict = foreground is not None and config.foreground_margin is not None
    fg = None
    if restrict:
        fg = foreground.view(np.uint8) if foreground.dtype == bool else foreground.astype(np.uint8)
        if not fg.any():
            return out
        reach = config.foreground_margin + int(np.ceil(EDGE_REACH * config.edge_sigma))
        rows, cols = _box(fg, reach)
        halo = int(np.ceil(4 * config.edge_blur_sigma)) + 2  # the blur's and Sobel's reach
        crows = slice(max(rows.start - halo, 0), min(rows.stop + halo, H))
        ccols = slice(max(cols.start - halo, 0), min(cols.stop + halo, W))
        grad = gradient_magnitude(image[crows, ccols], config.edge_blur_sigma)
        grad = grad[rows.start - crows.start:rows.stop - crows.start, cols.start - ccols.start:cols.stop - ccols.start]
        edges = grad > config.edge_threshold
        edges &= cv2.dilate(fg[rows, cols], _disc(config.foreground_margin)).astype(bool)
    else:
        rows, cols = slice(0, H), slice(0, W)
        edges = gradient_magnitude(image, config.edge_blur_sigma) > config.edge_threshold
    if not edges.any():
        return out
    dist = cv2.distanceTransform(np.logical_not(edges).view(np.uint8), cv2.DIST_L2, 5)
    dist *= dist
    dist /= np.float32(-2.0 * config.edge_sigma ** 2)
    out[rows, cols] = np.exp(dist)
    return out


@dataclass
class Observations:
    """One frame's observations over ``V`` views: ``silhouettes`` and ``edges``, each ``V x H x W`` float32
    in [0, 1]."""

    silhouettes: np.ndarray
    edges: np.ndarray

    @property
    def n_views(self) -> int:
        return len(self.silhouettes)


def observe(images: list[np.ndarray], backgrounds: list[np.ndarray | BackgroundPlate | None] | None = None,
            masks: list[np.ndarray | None] | None = None, config: ObservationConfig = DEFAULT_OBSERVATION,
            threads: int = 1) -> Observations:
    """Observations of one frame: per view a silhouette (the given mask if any, else background subtraction)
    and an edge map. Every view needs a mask or a background plate (a uint8 image, or a
    :class:`BackgroundPlate` prepared once for the sequence); the views' images share one size. ``threads``
    threads take the views in turn (OpenCV and the compiled steps release the interpreter lock); the result does
    not depend on it."""
    V = len(images)
    H, W = images[0].shape[:2] if V else (0, 0)
    for v, img in enumerate(images):
        if img.shape[:2] != (H, W):
            raise ValueError(f"view {v}: image of {img.shape[0]} x {img.shape[1]} pixels, view 0's is {H} x {W}")
        mask = None if masks is None else masks[v]
        if mask is not None and mask.shape != (H, W):
            raise ValueError(f"view {v}: mask of shape {mask.shape}, its image is {H} x {W} pixels")
    silhouettes = np.empty((V, H, W), np.float32)
    edges = np.empty((V, H, W), np.float32)

    def view(v: int) -> None:
        img = images[v]
        mask = None if masks is None else masks[v]
        if mask is None:
            bg = None if backgrounds is None else backgrounds[v]
            if bg is None:
                raise ValueError(f"view {v}: neither a foreground mask nor a background plate")
            mask = silhouette(img, bg, config)
        silhouettes[v] = mask
        edges[v] = edge_map(img, mask, config)

    share(view, range(V), threads)
    return Observations(silhouettes, edges)
