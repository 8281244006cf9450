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
from scipy.special import ndtri  # norm.ppf without importing scipy.stats (~1 s)

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
        # The upper median (the middle value, or the higher of the two middle ones), as a
        # histogram's cumulative count finds it; a partial sort of the copied sample gets
        # there at half the cost of bincount, which widens every pixel to intp first.
        values = sample.ravel()
        return float(np.partition(values, values.size // 2)[values.size // 2])
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


def _sample_grid(shape: tuple[int, ...], tile_px: int) -> tuple[slice, slice, int]:
    """Rows and columns of a sparse pixel sample, one every quarter tile, and the step."""
    step = max(int(tile_px) // 4, 1)
    # one line and column short of the far edges: each sample has a neighbour below and right
    return slice(step // 2, shape[0] - 1, step), slice(step // 2, shape[1] - 1, step), step


def _rank5(small: NDArray[np.float32], fraction: float) -> NDArray[np.float32]:
    """The value ``fraction`` of the way up each 5 x 5 neighbourhood of a small map."""
    if min(small.shape) < 5:
        return np.full_like(small, np.quantile(small, fraction))
    k = round(fraction * 24)
    if k == 12 and small.dtype == np.float32:
        # the median: OpenCV's 5 x 5 median filter repeats the edge as the padding below
        # does and selects the same value, at a fortieth of the partition's cost
        return cv2.medianBlur(small, 5)
    padded = np.pad(small, 2, mode="edge")
    windows = np.lib.stride_tricks.sliding_window_view(padded, (5, 5)).reshape(*small.shape, 25)
    return np.partition(windows, k, axis=-1)[..., k]


def _abs_diff_to_sigma(fraction: float) -> float:
    """Noise deviation per grey level of the ``fraction`` quantile of ``|a - b|``, ``a`` and
    ``b`` two pixels with independent Gaussian noise."""
    return 1.0 / (2**0.5 * float(ndtri((1.0 + fraction) / 2.0)))


@dataclass(frozen=True)
class LocalBackground:
    """The local background of an image, per pixel (float32 maps of the image's shape).

    Attributes
    ----------
    level : ndarray
        Background grey level: the median (or the given rank) of a sparse sample (two
        pixels every quarter tile) over 5 x 5 samples, about a tile. Spots covering less
        than half a tile do not move it; the edges of large bright regions are kept.
    slack : ndarray
        How far ``level`` may lag the true background because it is interpolated from
        tile-sized steps: half the range of the tile medians around each place. Zero on a
        flat or smoothly glowing background, large beside the edge of a bright region,
        where an unlagged background would otherwise leave a bright band of false spots.
    noise : ndarray
        Local noise deviation, from the differences of horizontally neighbouring pixels
        at the sample points (the same rank over a tile, scaled to a deviation).
        Bright surfaces are noisier (shot noise, texture) than dark ones.
    """

    level: NDArray[np.float32]
    slack: NDArray[np.float32]
    noise: NDArray[np.float32]


def local_background(image: NDArray, tile_px: int, rank: float = 0.5) -> LocalBackground:
    """The :class:`LocalBackground` of a grey image for tiles of about ``tile_px``.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grey image.
    tile_px : int
        Tile size in pixels; should be at least four times the largest marker's diameter.
    rank : float
        Which value of each neighbourhood of samples is the background: the median (0.5)
        follows gradients of glow exactly and ignores spots covering up to half a tile;
        a lower rank (0.25) also ignores dense grids of large dots, but reads low on
        steep gradients (used to judge how uneven a background is, not to subtract it).

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
    rows, cols, _ = _sample_grid(image.shape, tile_px)
    sample = image[rows, cols].astype(np.float32)
    below = np.minimum(rows.start + 1, h - 1)
    lower = image[below :: rows.step, cols].astype(np.float32)[: sample.shape[0]]
    level = _rank5(0.5 * (sample + lower), rank)  # two pixels per sample: half the noise
    box = np.ones((3, 3), np.uint8)
    slack = 0.5 * (cv2.dilate(level, box) - cv2.erode(level, box))
    right = image[rows, cols.start + 1 : cols.stop + 1 : cols.step].astype(np.float32)
    diff = np.abs(right[:, : sample.shape[1]] - sample)
    noise = _rank5(diff, rank) * np.float32(_abs_diff_to_sigma(rank))

    def full(m: NDArray[np.float32]) -> NDArray[np.float32]:
        return cv2.resize(m, (w, h), interpolation=cv2.INTER_LINEAR)

    return LocalBackground(full(level), full(slack), full(noise))


def background_map(image: NDArray, tile_px: int, rank: float = 0.5) -> NDArray[np.float32]:
    """The local background level alone (:attr:`LocalBackground.level`)."""
    return local_background(image, tile_px, rank).level
