"""Spot shape from second moments, corrected for the growth every spot gets.

Blur, blooming and the threshold widen a spot's white pixels by about the same amount in x
and y *in pixels*, whatever the marker's size. With non-square pixels that makes small
round markers look tall: the ratio tests of Shafiq et al. 2001, section 2.3.3 would split them. The
correction models each axis' spread as ``sigma_x = a + g`` and ``sigma_y = a / aspect + g``
(``a`` the marker's own spread along x, ``g`` the growth), so for a single round marker
``g = (sigma_x - aspect * sigma_y) / (1 - aspect)``. ``g`` is taken per image as the
median over its marker-sized groups (most of them single markers), which adapts to the
optics without a blur parameter; with too few groups the configured value is used.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

PIXEL_AREA_VAR = 1.0 / 12.0  # variance of a uniform pixel: part of every measured spread
#: Least ``|1 - pixel_aspect|`` at which the growth is estimated per image.
MIN_ASPECT_CONTRAST = 0.2


def spreads(
    var_x: NDArray[np.float64], var_y: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Standard deviations (pixels) of spots along x and y, pixel area removed."""
    return (
        np.sqrt(np.maximum(var_x - PIXEL_AREA_VAR, 1e-6)),
        np.sqrt(np.maximum(var_y - PIXEL_AREA_VAR, 1e-6)),
    )


def frame_growth(
    sigma_x: NDArray[np.float64],
    sigma_y: NDArray[np.float64],
    usable: NDArray[np.bool_],
    frames: tuple[NDArray[np.int64], int],
    pixel_aspect: float,
    fallback: float,
    min_groups: int,
) -> NDArray[np.float64]:
    """Growth ``g`` (pixels, in spread units) of each frame's spots; see the module notes.

    Parameters
    ----------
    sigma_x, sigma_y : ndarray
        Spreads of the groups (:func:`spreads`).
    usable : ndarray of bool
        Groups of marker size clear of the border.
    frames : (ndarray of int, int)
        Each group's frame and the number of frames.
    pixel_aspect : float
        Width / height of a round marker in pixels.
    fallback : float
        Used for a frame with fewer than ``min_groups`` usable groups.
    min_groups : int
        Least number of usable groups for a per-frame estimate.
    """
    frame, count = frames
    # (sigma_x - a sigma_y) / (1 - a) amplifies the spreads' noise by 1 / |1 - a|: near
    # square pixels the growth cannot be told from the marker, and the default stands
    if abs(1.0 - pixel_aspect) < MIN_ASPECT_CONTRAST:
        return np.full(count, fallback, dtype=float)
    own = frame[usable]
    per_group = (sigma_x[usable] - pixel_aspect * sigma_y[usable]) / (1.0 - pixel_aspect)
    median = frame_medians(per_group, own, count, fallback)
    return np.where(np.bincount(own, minlength=count) >= min_groups, median, fallback)


def corrected_moments(
    var_x: NDArray[np.float64],
    var_y: NDArray[np.float64],
    cov_xy: NDArray[np.float64],
    growth: float | NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Second moments with pixel area and growth removed (correlation kept); ``growth``
    one value, or one per group."""
    # x and y stacked: the same element-wise steps as spreads(), in half the numpy calls
    spread = np.sqrt(np.maximum(np.stack([var_x, var_y]) - PIXEL_AREA_VAR, 1e-6))
    rho = np.minimum(np.maximum(cov_xy / np.sqrt(np.maximum(var_x * var_y, 1e-12)), -1.0), 1.0)
    cx, cy = np.maximum(spread - growth, 0.05)
    return cx * cx, cy * cy, rho * cx * cy


def height_ratio(
    var_x: NDArray[np.float64], var_y: NDArray[np.float64], pixel_aspect: float
) -> NDArray[np.float64]:
    """Height-to-width ratio of spots from corrected moments, 1 for a round marker.

    The ratio of Shafiq et al. 2001, section 2.3.3 (h / w) taken from second moments rather than the
    bounding rectangle: a marker two or three lines high has a rectangle ratio that jumps
    with its sub-pixel position, while its moments change smoothly.
    """
    return pixel_aspect * np.sqrt(np.maximum(var_y, 1e-6) / np.maximum(var_x, 1e-6))


def principal_axes(
    var_x: NDArray[np.float64],
    var_y: NDArray[np.float64],
    cov_xy: NDArray[np.float64],
    pixel_aspect: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Principal axes of corrected spot moments in round units (x / ``pixel_aspect``).

    Returns the major and minor variances (round units squared) and the major axis
    direction ``(ux, uy)`` in round units (``uy`` > 0 points down the image).
    """
    a = var_x / pixel_aspect**2
    c = var_y
    b = cov_xy / pixel_aspect
    mean = (a + c) / 2
    half = np.sqrt(((a - c) / 2) ** 2 + b * b)
    theta = 0.5 * np.arctan2(2 * b, a - c)
    return mean + half, np.maximum(mean - half, 1e-3), np.cos(theta), np.sin(theta)


def frame_medians(
    values: NDArray, frame: NDArray[np.int64], count: int, empty: float
) -> NDArray[np.float64]:
    """The median of each frame's ``values`` (``empty`` for a frame without any): the middle
    value, or the mean of the two middle ones taken as ``(a + b) / 2``, as np.median does."""
    out = np.full(count, empty, dtype=float)
    if values.size == 0:
        return out
    ordered = values[np.lexsort((values, frame))]
    size = np.bincount(frame, minlength=count)
    has = size > 0
    first = (size.cumsum() - size)[has]
    half = size[has] // 2
    upper = ordered[first + half]
    lower = ordered[first + np.maximum(half - 1, 0)]
    out[has] = np.where(size[has] % 2 == 1, upper, (lower + upper) / 2)
    return out
