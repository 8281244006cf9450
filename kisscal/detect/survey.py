"""Measurements of a camera's images that its detection settings are derived from.

Everything here measures; :mod:`kisscal.detect.configure` decides. A *survey* of a few
frames finds the bright groups of each frame against the local background (a permissive
first threshold) and measures each group: white pixels, extent, peak contrast, second
moments and how far it is from its neighbours; and it measures the grey levels
(background, noise, how uneven the background is) and how far the blurred rim of a spot
reaches beyond its white pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.detect.advanced import Grouping
from kisscal.detect.background import (
    background_level,
    background_map,
    local_background,
    noise_sigma,
)
from kisscal.detect.centroid import window_moments
from kisscal.detect.groups import measure_groups
from kisscal.detect.noise import noise_groups
from kisscal.detect.params import DetectionParams
from kisscal.detect.scan import Runs, group_runs

#: Largest rim distance (px) measured beyond a spot's white pixels.
RIM_MAX_PX = 10
#: Margin (px) of the window over which a surveyed spot's grey moments are taken.
MOMENT_MARGIN_PX = 3
#: Groups of more than 1 / this of the image's pixels are too large for window moments.
SURVEY_WINDOW_FRACTION = 256
#: Local noise deviations a surveyed spot must stand above its local background.
NOISE_FACTOR = np.float32(DetectionParams().noise_factor)


@dataclass(frozen=True)
class GreyLevels:
    """Grey-level statistics of a set of frames (8-bit scale, as detection reads them).

    Attributes
    ----------
    background : float
        Median background level.
    noise : float
        Sensor noise standard deviation (:func:`kisscal.detect.background.noise_sigma`).
    unevenness : float
        Spread of the local background over the image (98th - 2nd percentile of the
        tile-median map): 0 for a uniformly dark surround.
    top : float
        Largest grey level seen.
    bits : int
        Bits of the stored data (8, 10, 12, 14 or 16), from the largest raw value.
    unit : float
        One grey level of an 8-bit camera in these frames' data, on the 8-bit scale: 1 for
        8-bit images and for 16-bit ones that use the whole range; 1/64 for a 10-bit
        camera's data stored unshifted in 16-bit images (its top is 1023, not 65535). The
        fixed floors of the derivation (a few grey levels) are in this unit.
    """

    background: float
    noise: float
    unevenness: float
    top: float
    bits: int
    unit: float = 1.0


def grey_levels(
    images: Sequence[NDArray], raw_max: Sequence[float], tile_px: int, container_levels: int = 256
) -> GreyLevels:
    """Background, noise and unevenness of checked images; ``raw_max`` of their raw data,
    ``container_levels`` the grey levels their type holds (256 for 8-bit, 65536 for 16)."""
    backgrounds, noises, spreads = [], [], []
    for image in images:
        backgrounds.append(background_level(image))
        noises.append(noise_sigma(image))
        bg = background_map(image, tile_px, rank=0.25)  # dense dots do not read as glow
        lo, hi = np.percentile(bg[::4, ::4], [2, 98])
        spreads.append(hi - lo)
    top = max(float(np.max(im)) for im in images)
    raw = max(raw_max) if len(raw_max) else 255.0
    bits = next((b for b in (8, 10, 12, 14, 16) if raw < 2**b), 16)
    return GreyLevels(
        float(np.median(backgrounds)),
        float(np.median(noises)),
        float(np.median(spreads)),
        top,
        bits,
        min(1.0, 2.0 ** max(bits, 8) / container_levels) if container_levels > 256 else 1.0,
    )


def structure_share(
    images: Sequence[NDArray], tile_px: int, small_px: int, excess: float, noise_factor: float
) -> float:
    """Share of the image where the background has structure at the markers' scale.

    The local background over tiles of ``small_px`` (a couple of marker diameters) is
    compared with the one over tiles of ``tile_px``: where the former stands above the
    latter by the white test's margin (``excess``, and ``noise_factor`` local noise
    deviations), something narrower than the large tile but wider than a marker is lit
    (the walls, edges and bands of a real scene) and the large tile's background would
    leave it white. A smooth glow follows both maps alike. The median over ``images``.
    """
    shares = []
    for image in images:
        large = local_background(image, tile_px)
        fine = background_map(image, small_px)
        above = np.maximum(np.float32(excess), np.float32(noise_factor) * large.noise)
        shares.append(float(np.mean(fine[::2, ::2] - large.level[::2, ::2] > above[::2, ::2])))
    return float(np.median(shares)) if shares else 0.0


@dataclass(frozen=True)
class Groups:
    """Bright groups of the surveyed frames, one row per group (all frames together).

    Attributes
    ----------
    frame : ndarray of int
    x, y : ndarray of float
        Binary centroid (px).
    pixels, width, height : ndarray of int
        White pixels and bounding rectangle.
    peak : ndarray of float
        Largest grey level above the background within the group.
    var_x, var_y : ndarray of float
        Second moments (px^2) of the spot's grey levels above the background over its
        rectangle grown by :data:`MOMENT_MARGIN_PX`: the blurred spot's own spread, not
        its thresholded outline (NaN from a survey without shapes).
    cov_xy : ndarray of float
        Their covariance (px^2): a spot elongated along a diagonal (a dot seen obliquely).
    fill : ndarray of float
        White pixels / bounding-rectangle pixels.
    inside : ndarray of bool
        Clear of the image border.
    isolation : ndarray of float
        Distance to the nearest other group's centroid, in units of this group's larger
        half-extent (large: well separated).
    """

    frame: NDArray[np.int64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    pixels: NDArray[np.int64]
    width: NDArray[np.int64]
    height: NDArray[np.int64]
    peak: NDArray[np.float64]
    var_x: NDArray[np.float64]
    var_y: NDArray[np.float64]
    cov_xy: NDArray[np.float64]
    fill: NDArray[np.float64]
    inside: NDArray[np.bool_]
    isolation: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.pixels)

    def take(self, rows: NDArray) -> Groups:
        """The groups at ``rows`` (indices or a mask)."""
        return Groups(*(getattr(self, f)[rows] for f in self.__dataclass_fields__))


def _run_pixels(runs: Runs) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Every white pixel of ``runs``: (run index, x, y)."""
    count = runs.length
    run_of = np.repeat(np.arange(len(runs)), count)
    x = runs.x1[run_of] + (np.arange(run_of.size) - np.repeat(np.cumsum(count) - count, count))
    return run_of, x, runs.y[run_of]


def survey_frame(
    image: NDArray, excess: float, tile_px: int, frame: int = 0, shapes: bool = True
) -> Groups:
    """The bright groups of one checked grey image: ``excess`` above the local background
    (and above its local noise and interpolation slack, as detection's local mode).

    Noise groups (lonely pixels, one pixel wide or high) are left out. Without
    ``shapes`` the window moments (most of the survey's time) are not taken: ``var_x``,
    ``var_y`` and ``cov_xy`` are NaN.
    """
    local = local_background(image, tile_px)
    bg = local.level
    contrast = image.astype(np.float32) - bg
    above = np.maximum(np.float32(excess), NOISE_FACTOR * local.noise) + local.slack
    white = contrast >= above
    runs = group_runs(white)
    table = measure_groups(runs)
    keep = ~noise_groups(table, DetectionParams())
    run_of, x, y = _run_pixels(runs)
    slot = np.searchsorted(table.label, runs.group[run_of])
    peak = np.full(len(table), -np.inf)
    np.maximum.at(peak, slot, contrast[y, x])
    var_x = var_y = cov_xy = np.full(len(table), np.nan)
    if shapes:
        m = MOMENT_MARGIN_PX
        # glare, lit surfaces: their own pixels' moments (their rectangles may span the image)
        windowed = table.pixels <= max(image.size // SURVEY_WINDOW_FRACTION, 64)
        grouping = Grouping.start(runs)
        moments = window_moments(image, white, grouping, table, m, m, bg, 1.0, windowed)
        var_x, var_y, cov_xy = moments.var_x, moments.var_y, moments.cov_xy
    h, w = image.shape
    inside = (table.x1 > 0) & (table.y1 > 0) & (table.x2 < w - 1) & (table.y2 < h - 1)
    centres = np.column_stack([table.x_binary, table.y_binary])
    size = np.maximum(table.width, table.height) / 2.0
    if len(table) > 1:
        dist, _ = cKDTree(centres).query(centres, k=2)
        isolation = dist[:, 1] / size
    else:
        isolation = np.full(len(table), np.inf)
    groups = Groups(
        np.full(len(table), frame),
        table.x_binary,
        table.y_binary,
        table.pixels,
        table.width,
        table.height,
        peak.astype(float),
        var_x,
        var_y,
        cov_xy,
        table.fill,
        inside,
        isolation,
    )
    return groups.take(keep)


def survey_frames(
    images: Sequence[NDArray], excess: float, tile_px: int, shapes: bool = True
) -> Groups:
    """:func:`survey_frame` of every image, stacked."""
    parts = [survey_frame(im, excess, tile_px, k, shapes) for k, im in enumerate(images)]
    return Groups(
        *(np.concatenate([getattr(p, f) for p in parts]) for f in Groups.__dataclass_fields__)
    )


def stationary(groups: Groups, radius_px: float = 1.5, fraction: float = 0.6) -> NDArray[np.bool_]:
    """Groups at a place where most surveyed frames have a group (LED rings, reflections).

    Moving markers pass any place in a few frames at most; the LED rings of facing cameras
    and fixed reflections sit in every frame (Küçük 2005, 3.3.1). Needs five frames or
    more; with fewer, nothing is called stationary.
    """
    n_frames = len(np.unique(groups.frame))
    if n_frames < 5 or len(groups) == 0:
        return np.zeros(len(groups), dtype=bool)
    xy = np.column_stack([groups.x, groups.y])
    count = cKDTree(xy).query_ball_point(xy, radius_px, return_length=True)
    return np.asarray(count) >= fraction * n_frames


def marker_mask(white: NDArray[np.bool_], max_pixels: int | None) -> NDArray[np.bool_]:
    """``white`` without its groups of more than ``max_pixels`` (LED rings and their flare)."""
    if max_pixels is None:
        return white
    runs = group_runs(white)
    table = measure_groups(runs)
    big = np.zeros(int(runs.group.max()) + 1 if len(runs) else 0, dtype=bool)
    big[table.label[table.pixels > max_pixels]] = True
    keep = runs.take(~big[runs.group])
    _, x, y = _run_pixels(keep)
    mask = np.zeros_like(white)
    mask[y, x] = True
    return mask


def rim_reach_px(
    image: NDArray, white: NDArray[np.bool_], background: float | NDArray, floor: float
) -> tuple[int, int]:
    """How far (px) the blurred rim of the spots reaches beyond their white pixels, in x
    and in y.

    The pixels at each horizontal (vertical) distance from the nearest white pixel form a
    ring; the rim ends at the first distance whose mean grey level is within ``floor`` of
    the far rings' (distances :data:`RIM_MAX_PX` + 1 and + 2), so that a glow around the
    spots, not part of their image, does not count.
    """
    contrast = image.astype(np.float32) - np.asarray(background, dtype=np.float32)
    mask = white.astype(np.uint8)
    reach = []
    for axis in (0, 1):
        means = []
        inner = mask
        for d in range(1, RIM_MAX_PX + 3):
            size = (2 * d + 1, 1) if axis == 0 else (1, 2 * d + 1)
            outer = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_RECT, size))
            ring = (outer > 0) & (inner == 0)
            means.append(float(contrast[ring].mean()) if ring.any() else 0.0)
            inner = outer
        far = float(np.mean(means[-2:]))
        near = np.flatnonzero(np.asarray(means[:RIM_MAX_PX]) - far < floor)
        reach.append(int(near[0]) + 1 if near.size else RIM_MAX_PX)
    return reach[0], reach[1]
