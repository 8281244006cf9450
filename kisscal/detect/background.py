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


def _as_uint8(image: NDArray) -> tuple[NDArray[np.uint8], float]:
    """The image on an 8-bit scale for OpenCV's fast median, and the factor to undo it."""
    if image.dtype == np.uint8:
        return image, 1.0
    top = float(image.max()) if image.size else 0.0
    scale = 255.0 / top if top > 255.0 else 1.0
    return np.clip(image * scale, 0, 255).astype(np.uint8), scale


def background_map(image: NDArray, tile_px: int) -> NDArray[np.float32]:
    """Local background of every pixel: the median over tiles of about ``tile_px``.

    The image is averaged down by a factor of a quarter tile (block means; a marker much
    smaller than a tile barely moves them), a 5 x 5 median over the small image (so over
    about one tile) removes what is left of the markers while keeping the edges of large
    bright regions, and the result is interpolated back to full size.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grey image.
    tile_px : int
        Tile size in pixels; should be at least four times the largest marker's diameter.

    Returns
    -------
    ndarray of float32, shape (h, w)
        Background grey level per pixel, on the image's own scale.

    Examples
    --------
    >>> import numpy as np
    >>> glow = np.tile(np.linspace(10, 90, 200), (120, 1))     # a left-to-right glow
    >>> image = glow.astype(np.uint8)
    >>> image[50:55, 100:105] = 250                            # one marker
    >>> bg = background_map(image, 40)
    >>> bool(abs(bg[52, 102] - glow[52, 102]) < 3)
    True
    """
    h, w = image.shape
    factor = max(int(tile_px) // 4, 1)
    small_size = (max(w // factor, 1), max(h // factor, 1))
    grey, scale = _as_uint8(image)
    small = cv2.resize(grey, small_size, interpolation=cv2.INTER_AREA)
    if min(small.shape) >= 5:
        small = cv2.medianBlur(small, 5)
    full = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float32)
    return full / np.float32(scale) if scale != 1.0 else full
