"""Background level, sensor noise and the white test of an IR image.

A marker image is a small bright population over a dark background. Where the background
is flat (a dark lab, a well-exposed IR camera) one level per image serves both the
threshold and the weighted centroids. Where it is not (a glowing plate, daylight through a
window, a bright surround beside a dark calibration target) a single grey-level threshold
either swallows whole bright regions as one blob or loses faint markers, and a single
background level biases the weighted centroids. The *local* background is then the
median over tiles larger than any marker, which ignores the markers themselves and follows
the glow; a pixel is white when it stands ``threshold`` grey levels above it (the same idea
as a local, adaptive threshold).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

#: Pixels of the sparse sample taken for the global statistics (every n-th line and column).
SAMPLE_STEP = 4


def background_level(image: NDArray) -> float:
    """Median grey level of a sparse sample of ``image`` (every 4th line and column).

    Marker images are mostly background, so the median of any spread-out sample is the
    background level even with a few large LED blobs in view.

    Examples
    --------
    >>> import numpy as np
    >>> image = np.full((40, 60), 6, np.uint8)
    >>> image[10:14, 20:26] = 250
    >>> background_level(image)
    6.0
    """
    sample = image[::SAMPLE_STEP, ::SAMPLE_STEP]
    if sample.dtype == np.uint8:
        counts = np.bincount(sample.ravel(), minlength=256)
        return float(np.searchsorted(np.cumsum(counts), (sample.size + 1) / 2))
    return float(np.median(sample))


def noise_sigma(image: NDArray) -> float:
    """Standard deviation of the sensor noise, robust to markers and smooth glow.

    From horizontally neighbouring pixels: their difference cancels any background that
    varies slowly, and its median absolute value ignores the few differences across
    marker edges. For Gaussian noise of deviation ``s`` the differences have deviation
    ``s sqrt(2)``, hence ``1.4826 median|d| / sqrt(2)`` (Rousseeuw & Croux 1993).

    References
    ----------
    Rousseeuw, P. J., & Croux, C. (1993). Alternatives to the median absolute deviation.
    Journal of the American Statistical Association, 88(424), 1273-1283.
    """
    rows = image[::SAMPLE_STEP].astype(np.float32)
    diff = np.abs(rows[:, 1:] - rows[:, :-1])
    return float(1.4826 * np.median(diff) / np.sqrt(2.0))


def _small_size(shape: tuple[int, ...], tile_px: int) -> tuple[int, int]:
    """Size of the block-averaged image: blocks of a quarter tile."""
    h, w = shape
    factor = max(int(tile_px) // 4, 1)
    return max(w // factor, 1), max(h // factor, 1)


def _median5(small: NDArray[np.float32]) -> NDArray[np.float32]:
    """A 5 x 5 median of a small float map (through 8 bits: OpenCV's fast path)."""
    if min(small.shape) < 5:
        return small
    top = float(small.max())
    scale = 255.0 / top if top > 0 else 1.0
    as8 = np.clip(small * scale + 0.5, 0, 255).astype(np.uint8)
    return cv2.medianBlur(as8, 5).astype(np.float32) / np.float32(scale)


@dataclass(frozen=True)
class LocalBackground:
    """The local background of an image, per pixel (float32 maps of the image's shape).

    Attributes
    ----------
    level : ndarray
        Background grey level: the median over tiles (markers, much smaller than a tile,
        do not move it; the edges of large bright regions are kept).
    slack : ndarray
        How far ``level`` may lag the true background because it is interpolated from
        tile-sized steps: half the range of the tile medians around each place. Zero on a
        flat or smoothly glowing background, large beside the edge of a bright region,
        where an unlagged background would otherwise leave a bright band of false spots.
    noise : ndarray
        Local noise deviation: the grey-level spread within quarter-tile blocks, median
        smoothed over a tile. Bright surfaces are noisier (shot noise, texture) than
        dark ones.
    """

    level: NDArray[np.float32]
    slack: NDArray[np.float32]
    noise: NDArray[np.float32]


def local_background(image: NDArray, tile_px: int) -> LocalBackground:
    """The :class:`LocalBackground` of a grey image for tiles of about ``tile_px``.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grey image.
    tile_px : int
        Tile size in pixels; should be at least four times the largest marker's diameter.

    Examples
    --------
    >>> import numpy as np
    >>> glow = np.tile(np.linspace(10, 90, 200), (120, 1))     # a left-to-right glow
    >>> image = glow.astype(np.uint8)
    >>> image[50:55, 100:105] = 250                            # one marker
    >>> bg = local_background(image, 40)
    >>> bool(abs(bg.level[52, 102] - glow[52, 102]) < 3), bool(bg.slack[52, 102] < 5)
    (True, True)
    """
    h, w = image.shape
    size = _small_size(image.shape, tile_px)
    grey = image.astype(np.float32)
    mean = cv2.resize(grey, size, interpolation=cv2.INTER_AREA)
    square = cv2.resize(grey * grey, size, interpolation=cv2.INTER_AREA)
    level = _median5(mean)
    box = np.ones((3, 3), np.uint8)
    slack = 0.5 * (cv2.dilate(level, box) - cv2.erode(level, box))
    noise = _median5(np.sqrt(np.maximum(square - mean * mean, 0.0)))

    def full(m: NDArray[np.float32]) -> NDArray[np.float32]:
        return cv2.resize(m, (w, h), interpolation=cv2.INTER_LINEAR)

    return LocalBackground(full(level), full(slack), full(noise))


def background_map(image: NDArray, tile_px: int) -> NDArray[np.float32]:
    """The local background level alone (:attr:`LocalBackground.level`)."""
    return local_background(image, tile_px).level
