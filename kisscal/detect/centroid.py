"""Intensity-weighted sub-pixel centroids and spot moments (DESIGN.md centroid convention).

The binary centroid of equation (2) only sees the pixels above the threshold, so it moves
in steps as the marker's sub-pixel position changes. The weighted centroid sums
``(I - background)`` over the group's bounding rectangle grown by a margin, so the blurred
rim below the threshold counts too; subtracting the background keeps the flat surround
from pulling the centroid towards the window's centre. White pixels of *other* groups
(neighbouring markers, noise pixels) inside the window are left out, and the parts of a
split group share the window by nearest estimated centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.advanced import Grouping
from kisscal.detect.groups import GroupTable

#: The background a spot's weights are measured from: one grey level, or a map per pixel.
Background = float | NDArray[np.floating]


@dataclass(frozen=True)
class SpotMoments:
    """Weighted moments of each group's window: total weight, centroid, central moments.

    ``core_var_x`` / ``core_var_y`` are the central moments over the group's own white
    pixels only (same weights): insensitive to the background level and to noise in the
    window's wide margin, which dominate the full-window second moments of small spots.
    """

    total: NDArray[np.float64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    var_x: NDArray[np.float64]
    var_y: NDArray[np.float64]
    cov_xy: NDArray[np.float64]
    core_var_x: NDArray[np.float64]
    core_var_y: NDArray[np.float64]
    core_cov_xy: NDArray[np.float64]


def owner_image(shape: tuple[int, int], grouping: Grouping) -> NDArray[np.int32]:
    """Image of ``label + 1`` at every white pixel of a remaining group, 0 elsewhere."""
    owner = np.zeros(shape, dtype=np.int32)  # calloc: untouched pages cost nothing
    runs = grouping.runs
    count = runs.length
    run_of = np.repeat(np.arange(len(runs)), count)
    x = runs.x1[run_of] + (np.arange(run_of.size) - np.repeat(np.cumsum(count) - count, count))
    owner[runs.y[run_of], x] = runs.group[run_of] + 1
    return owner


def window_moments(
    image: NDArray,
    white: NDArray[np.bool_],
    owner: NDArray[np.int32],
    grouping: Grouping,
    table: GroupTable,
    margin_x_px: int,
    margin_y_px: int,
    background: Background,
    pixel_aspect: float,
) -> SpotMoments:
    """Background-subtracted weighted moments of each group in ``table`` over its window.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grey image (or the boolean image itself, then each own white pixel weighs 1).
    white : ndarray of bool
        The thresholded image: white pixels not owned by the group get no weight.
    owner : ndarray of int32
        :func:`owner_image` of ``grouping``.
    grouping : Grouping
        For parts of a split group, their parent and estimated centres: a window pixel
        counts for a part only when it is nearer its centre than any sibling's.
    table : GroupTable
        Bounding rectangles of the groups.
    margin_x_px, margin_y_px : int
        Growth of each rectangle to take in the blurred rim.
    background : float or ndarray
        Grey level subtracted from every pixel before weighting: one level, or a map of
        the image's shape (local background).
    pixel_aspect : float
        Width / height of a round marker in pixels (nearest-centre distance).

    Returns
    -------
    SpotMoments
        The centroid falls back to the binary centroid where the weights sum to <= 0 or
        put it outside the window.
    """
    height, width = image.shape
    n = len(table)
    x0 = np.maximum(table.x1 - margin_x_px, 0)
    x1 = np.minimum(table.x2 + margin_x_px, width - 1)
    y0 = np.maximum(table.y1 - margin_y_px, 0)
    y1 = np.minimum(table.y2 + margin_y_px, height - 1)
    ncol = x1 - x0 + 1
    area = ncol * (y1 - y0 + 1)
    first = np.cumsum(area) - area
    g = np.repeat(np.arange(n), area)
    k = np.arange(g.size) - first[g]
    row, col = np.divmod(k, ncol[g])
    ys = y0[g] + row
    xs = x0[g] + col
    flat = ys * width + xs
    own = owner.ravel().take(flat) == table.label[g] + 1
    if image.dtype == np.bool_:
        weight = own.astype(np.float64)
    else:
        weight = image.ravel().take(flat).astype(np.float64)
        weight -= background.ravel().take(flat) if np.ndim(background) else background
        weight[white.ravel().take(flat) & ~own] = 0.0
    split = np.flatnonzero(~np.isnan(grouping.centre_x[table.label]))
    if split.size:
        weight *= _nearest_part_mask(g, xs, ys, split, grouping, table, pixel_aspect)
    # Raw moments about each window's corner (small numbers: no cancellation), all in one
    # segment reduction since each window's pixels are contiguous.
    lx = col.astype(np.float64)
    ly = row.astype(np.float64)
    core = weight * own
    terms = np.stack(
        [
            weight,
            weight * lx,
            weight * ly,
            weight * lx * lx,
            weight * ly * ly,
            weight * lx * ly,
            core,
            core * lx,
            core * ly,
            core * lx * lx,
            core * ly * ly,
            core * lx * ly,
        ]
    )
    sums = np.add.reduceat(terms, first, axis=1)
    total, core_total = sums[0], sums[6]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        t = np.where(total > 0, total, 1.0)
        ct = np.where(core_total > 0, core_total, 1.0)
        mx, my = sums[1] / t, sums[2] / t
        cx, cy = sums[7] / ct, sums[8] / ct
        # weights that (nearly) cancel put a centroid anywhere: keep it only inside its
        # window, else the binary centroid stands
        nrow = y1 - y0 + 1
        ok = (total > 0) & (mx >= 0) & (mx <= ncol - 1) & (my >= 0) & (my <= nrow - 1)
        return SpotMoments(
            total=total,
            x=np.where(ok, x0 + mx, table.x_binary),
            y=np.where(ok, y0 + my, table.y_binary),
            var_x=sums[3] / t - mx * mx,
            var_y=sums[4] / t - my * my,
            cov_xy=sums[5] / t - mx * my,
            core_var_x=sums[9] / ct - cx * cx,
            core_var_y=sums[10] / ct - cy * cy,
            core_cov_xy=sums[11] / ct - cx * cy,
        )


def _nearest_part_mask(
    g: NDArray[np.int64],
    xs: NDArray[np.int64],
    ys: NDArray[np.int64],
    split: NDArray[np.int64],
    grouping: Grouping,
    table: GroupTable,
    pixel_aspect: float,
) -> NDArray[np.float64]:
    """1.0 where a window pixel of a split part is nearer its own centre than a sibling's.

    One pass over the window pixels of all split parts: each pixel is compared with the
    centres of its part's siblings only (at most a few), so the cost is linear in the
    number of window pixels whatever the number of split groups.
    """
    keep = np.ones(g.size)
    parent = grouping.parent[table.label]
    order = split[np.argsort(parent[split], kind="stable")]
    first = np.flatnonzero(np.r_[True, parent[order][1:] != parent[order][:-1]])
    count = np.diff(np.r_[first, order.size])
    family = np.repeat(np.arange(first.size), count)  # sibling set of each split row
    siblings = np.full((first.size, int(count.max())), -1)
    siblings[family, np.arange(order.size) - first[family]] = order
    family_of_row = np.full(len(table), -1)
    family_of_row[order] = family
    rows = np.flatnonzero(family_of_row[g] >= 0)
    cand = siblings[family_of_row[g[rows]]]  # (pixels, siblings), -1 padded
    safe = np.maximum(cand, 0)
    cx = grouping.centre_x[table.label[safe]]
    cy = grouping.centre_y[table.label[safe]]
    r2 = grouping.radius[table.label[safe]] ** 2
    d = (((xs[rows, None] - cx) / pixel_aspect) ** 2 + (ys[rows, None] - cy) ** 2) / r2
    d[cand < 0] = np.inf
    nearest = cand[np.arange(rows.size), np.argmin(d, axis=1)]
    keep[rows] = nearest == g[rows]
    return keep
