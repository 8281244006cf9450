"""Intensity-weighted sub-pixel centroids (DESIGN.md centroid convention).

The binary centroid of equation (2) only sees the pixels above the threshold, so it moves
in steps as the marker's sub-pixel position changes. The weighted centroid sums
``(I - background)`` over the group's bounding rectangle grown by a margin, so the blurred
rim below the threshold counts too; subtracting the background keeps the flat surround
from pulling the centroid towards the window's centre.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.advanced import Grouping
from kisscal.detect.groups import GroupTable


def estimate_background(image: NDArray) -> float:
    """Median grey level of a sparse sample of ``image`` (every 4th line and column).

    Marker images are mostly background, so the median of any spread-out sample is the
    background level even with a few large LED blobs in view.
    """
    sample = image[::4, ::4]
    if sample.dtype == np.uint8:
        counts = np.bincount(sample.ravel(), minlength=256)
        return float(np.searchsorted(np.cumsum(counts), (sample.size + 1) / 2))
    return float(np.median(sample))


def weighted_centroids(
    image: NDArray,
    grouping: Grouping,
    table: GroupTable,
    margin_x_px: int,
    margin_y_px: int,
    background: float,
    pixel_aspect: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Background-subtracted intensity-weighted centroid of each group in ``table``.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grayscale image the groups were found in.
    grouping : Grouping
        Gives, for parts of a split group, their parent and estimated centres: a window
        pixel counts for a part only when it is nearer its centre than any sibling's, so
        the shared rim is divided between the overlapping markers.
    table : GroupTable
        Bounding rectangles of the groups.
    margin_x_px, margin_y_px : int
        Growth of each rectangle to take in the blurred rim.
    background : float
        Grey level subtracted from every pixel before weighting.
    pixel_aspect : float
        Width / height of a round marker in pixels (nearest-centre distance).

    Returns
    -------
    x, y : ndarray of float
        Centroids in pixels; the binary centroid where the weights sum to <= 0.
    """
    height, width = image.shape
    n = len(table)
    x0 = np.maximum(table.x1 - margin_x_px, 0)
    x1 = np.minimum(table.x2 + margin_x_px, width - 1)
    y0 = np.maximum(table.y1 - margin_y_px, 0)
    y1 = np.minimum(table.y2 + margin_y_px, height - 1)
    ncol = x1 - x0 + 1
    area = ncol * (y1 - y0 + 1)
    g = np.repeat(np.arange(n), area)
    k = np.arange(g.size) - np.repeat(np.cumsum(area) - area, area)
    ys = y0[g] + k // ncol[g]
    xs = x0[g] + k % ncol[g]
    weight = image[ys, xs].astype(np.float64) - background
    parent = grouping.parent[table.label]
    split = np.flatnonzero(~np.isnan(grouping.centre_x[table.label]))
    if split.size:
        weight *= _nearest_part_mask(g, xs, ys, split, parent, grouping, table, pixel_aspect)
    total = np.bincount(g, weight, minlength=n)
    sx = np.bincount(g, weight * xs, minlength=n)
    sy = np.bincount(g, weight * ys, minlength=n)
    ok = total > 0
    x = np.where(ok, sx / np.where(ok, total, 1), table.x_binary)
    y = np.where(ok, sy / np.where(ok, total, 1), table.y_binary)
    return x, y


def _nearest_part_mask(
    g: NDArray[np.int64],
    xs: NDArray[np.int64],
    ys: NDArray[np.int64],
    split: NDArray[np.int64],
    parent: NDArray[np.int64],
    grouping: Grouping,
    table: GroupTable,
    pixel_aspect: float,
) -> NDArray[np.float64]:
    """1.0 where a window pixel of a split part is nearer its own centre than a sibling's."""
    keep = np.ones(g.size)
    cx = grouping.centre_x[table.label]
    cy = grouping.centre_y[table.label]
    for p in np.unique(parent[split]):
        members = split[parent[split] == p]
        rows = np.isin(g, members)
        d = ((xs[rows, None] - cx[members]) / pixel_aspect) ** 2 + (
            ys[rows, None] - cy[members]
        ) ** 2
        nearest = members[np.argmin(d, axis=1)]
        keep[rows] = nearest == g[rows]
    return keep
