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


def window_moments(
    image: NDArray,
    white: NDArray[np.bool_],
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
    grouping : Grouping
        The groups' runs (which white pixels a group owns) and, for parts of a split
        group, their parent and estimated centres: a window pixel counts for a part only
        when it is nearer its centre than any sibling's. Every run's label is in ``table``.
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
    ncol = np.minimum(table.x2 + margin_x_px, width - 1) - x0 + 1
    y0 = np.maximum(table.y1 - margin_y_px, 0)
    nrow = np.minimum(table.y2 + margin_y_px, height - 1) - y0 + 1
    area = ncol * nrow
    first = area.cumsum() - area
    # Every window's pixels, window after window, each in scan order.
    g = np.arange(n).repeat(area)
    row, col = np.divmod(np.arange(g.size) - first[g], ncol[g])
    flat = (y0 * width + x0)[g] + row * width + col
    own = _own_pixels(grouping, table, first, x0, y0, ncol, g.size)
    # Raw moments about each window's corner (small numbers: no cancellation) of the
    # window's weights and of its own pixels' weights (core), all in one segment
    # reduction since each window's pixels are contiguous. Terms 1, x, y, x^2, y^2, xy,
    # each product taken as (w x) x etc. so that the sums stay those of w * x * x, and
    # written in place: the terms are most of the pixel-level work.
    terms = np.empty((6, 2, g.size))
    weight = terms[0, 0]
    if image.dtype == np.bool_:
        weight[:] = own
    else:
        bg = background.ravel().take(flat) if np.ndim(background) else background
        np.subtract(image.ravel().take(flat), bg, out=weight, dtype=np.float64)
        weight[white.ravel().take(flat) & ~own] = 0.0
    split = (~np.isnan(grouping.centre_x[table.label])).nonzero()[0]
    if split.size:
        xs, ys = x0[g] + col, y0[g] + row
        weight *= _nearest_part_mask(g, xs, ys, split, grouping, table, pixel_aspect)
    np.multiply(weight, own, out=terms[0, 1])
    w = terms[0]
    np.multiply(w, col, out=terms[1])
    np.multiply(w, row, out=terms[2])
    np.multiply(terms[1], col, out=terms[3])
    np.multiply(terms[2], row, out=terms[4])
    np.multiply(terms[1], row, out=terms[5])
    sums = np.add.reduceat(terms, first, axis=2).transpose(1, 0, 2)
    return _moments_from_sums(sums, table, x0, y0, ncol, nrow)


#: The centroid coordinates (x, y) whose products make the central terms x^2, y^2, xy.
_LEFT = np.array([0, 1, 0])
_RIGHT = np.array([0, 1, 1])


def _own_pixels(
    grouping: Grouping,
    table: GroupTable,
    first: NDArray[np.int64],
    x0: NDArray[np.int64],
    y0: NDArray[np.int64],
    ncol: NDArray[np.int64],
    size: int,
) -> NDArray[np.bool_]:
    """Which window pixels are white pixels of the window's own group.

    Each run lies inside its group's window, so its pixels are scattered straight to
    their window positions: no image-sized owner map to clear and look up.
    """
    runs = grouping.runs
    row = table.label.searchsorted(runs.group)
    # position of image pixel (x, y) in window t: first + (y - y0) ncol + (x - x0)
    offset = (first - y0 * ncol - x0)[row] + runs.y * ncol[row] + runs.x1
    count = runs.x2 - runs.x1 + 1
    end = count.cumsum()
    own = np.zeros(size, dtype=bool)
    pixels = int(end[-1]) if end.size else 0
    own[np.arange(pixels) + (offset - end + count).repeat(count)] = True
    return own


def _moments_from_sums(
    sums: NDArray[np.float64],
    table: GroupTable,
    x0: NDArray[np.int64],
    y0: NDArray[np.int64],
    ncol: NDArray[np.int64],
    nrow: NDArray[np.int64],
) -> SpotMoments:
    """Centroids and central moments from the raw window sums ``(window | core, term, group)``.

    Totals <= 0 divide by 1 instead (never by zero), and the centroid then falls back to
    the binary one.
    """
    total = sums[:, 0]
    positive = total > 0
    # E[x], E[y], E[x^2], E[y^2], E[xy] of the window and of the core, one division
    expect = sums[:, 1:] / np.where(positive, total, 1.0)[:, None]
    # var_x, var_y, cov_xy: E[x^2] - x x, E[y^2] - y y, E[xy] - x y
    central = expect[:, 2:] - expect[:, _LEFT] * expect[:, _RIGHT]
    mx, my = expect[0, :2]
    # weights that (nearly) cancel put a centroid anywhere: keep it only inside its
    # window, else the binary centroid stands
    ok = positive[0] & (np.minimum(mx, my) >= 0) & (mx <= ncol - 1) & (my <= nrow - 1)
    return SpotMoments(
        total=total[0],
        x=np.where(ok, x0 + mx, table.x_binary),
        y=np.where(ok, y0 + my, table.y_binary),
        var_x=central[0, 0],
        var_y=central[0, 1],
        cov_xy=central[0, 2],
        core_var_x=central[1, 0],
        core_var_y=central[1, 1],
        core_cov_xy=central[1, 2],
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
    family_parent = parent[order]
    new_family = np.ones(order.size, dtype=bool)
    np.not_equal(family_parent[1:], family_parent[:-1], out=new_family[1:])
    first = new_family.nonzero()[0]
    count = np.empty_like(first)  # family sizes (np.diff's append= costs more)
    count[:-1] = first[1:] - first[:-1]
    count[-1] = order.size - first[-1]
    family = np.arange(first.size).repeat(count)  # sibling set of each split row
    siblings = np.full((first.size, int(count.max())), -1)
    siblings[family, np.arange(order.size) - first[family]] = order
    family_of_row = np.full(len(table), -1)
    family_of_row[order] = family
    rows = (family_of_row[g] >= 0).nonzero()[0]
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
