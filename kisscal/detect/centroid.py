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
from kisscal.detect.scan import Runs
from kisscal.detect.stack import Frames, background_at

#: The background a spot's weights are measured from: one grey level, a map per pixel,
#: or for stacked frames (:mod:`kisscal.detect.stack`) one level per frame.
Background = float | NDArray[np.floating]


@dataclass(frozen=True)
class SpotMoments:
    """Weighted moments of each group's window: centroid and central moments.

    ``core_var_x`` / ``core_var_y`` are the central moments over the group's own white
    pixels only (same weights): insensitive to the background level and to noise in the
    window's wide margin, which dominate the full-window second moments of small spots.
    """

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
    windowed: NDArray[np.bool_] | None = None,
    frames: Frames | None = None,
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
        Grey level subtracted from every pixel before weighting: one level, a map of
        the image's shape (local background), or one level per frame of ``frames``.
    pixel_aspect : float
        Width / height of a round marker in pixels (nearest-centre distance).
    windowed : ndarray of bool, optional
        The groups whose window is weighed (default: all). The others (glare, lit
        surfaces: groups far larger than a marker, whose rectangles may span the image)
        get the plain moments of their own white pixels (:func:`binary_moments`), so
        that the cost follows the white pixels, not the rectangles' areas.
    frames : Frames, optional
        The frames stacked in ``image`` (default: one): the groups are in their own
        frame's coordinates (:func:`~kisscal.detect.stack.unstack`) and read the image
        at their frame's rows.

    Returns
    -------
    SpotMoments
        The centroid falls back to the binary centroid where the weights sum to <= 0 or
        put it outside the window.
    """
    if windowed is not None and not windowed.all():
        return _partly_windowed(
            image,
            white,
            grouping,
            table,
            (margin_x_px, margin_y_px),
            background,
            pixel_aspect,
            windowed,
            frames,
        )
    width = image.shape[1]
    height = image.shape[0] if frames is None else frames.height
    x0 = np.maximum(table.x1 - margin_x_px, 0)
    ncol = np.minimum(table.x2 + margin_x_px, width - 1) - x0 + 1
    y0 = np.maximum(table.y1 - margin_y_px, 0)
    nrow = np.minimum(table.y2 + margin_y_px, height - 1) - y0 + 1
    windows = _Windows(x0, y0, ncol, nrow)
    frame = None if frames is None else frames.of(grouping, table)
    stacked = (frames, frame)
    spot = _Spot(image, white, grouping, table, background, pixel_aspect, stacked)
    area = ncol * nrow
    if int(area.sum()) <= WINDOW_CHUNK_PX:  # the usual image: every window at once
        sums = _window_sums(spot, windows, np.arange(len(table)), 0, nrow)
    else:
        sums = _chunked_sums(spot, windows)
    return _moments_from_sums(sums, table, x0, y0, ncol, nrow)


def _partly_windowed(
    image: NDArray,
    white: NDArray[np.bool_],
    grouping: Grouping,
    table: GroupTable,
    margins: tuple[int, int],
    background: Background,
    pixel_aspect: float,
    windowed: NDArray[np.bool_],
    frames: Frames | None,
) -> SpotMoments:
    """Window moments of the ``windowed`` groups, binary moments of the others."""
    plain = binary_moments(grouping.runs, table)
    if not windowed.any():
        return plain
    mine = np.zeros(int(table.label.max()) + 1, dtype=bool)
    mine[table.label[windowed]] = True
    part = grouping.relabel(grouping.runs.take(mine[grouping.runs.group]))
    sub = table.take(windowed)
    some = window_moments(
        image, white, part, sub, *margins, background, pixel_aspect, frames=frames
    )
    out = {}
    for name in SpotMoments.__dataclass_fields__:
        column = getattr(plain, name).copy()
        column[windowed] = getattr(some, name)
        out[name] = column
    return SpotMoments(**out)


def binary_moments(runs: Runs, table: GroupTable) -> SpotMoments:
    """Moments of each group's own white pixels, each weighing 1 (window and core alike).

    Summed run by run in closed form (a run's sum of x and x^2 over its columns), so the
    cost is one pass over the runs whatever the groups' rectangles.
    """
    row = table.label.searchsorted(runs.group)
    n = (runs.x2 - runs.x1 + 1).astype(float)
    x1, x2, y = runs.x1.astype(float), runs.x2.astype(float), runs.y.astype(float)
    # about each group's rectangle corner: small numbers, no cancellation
    x1 -= table.x1[row]
    x2 -= table.x1[row]
    y -= table.y1[row]
    sx = n * (x1 + x2) / 2
    sxx = (x2 * (x2 + 1) * (2 * x2 + 1) - (x1 - 1) * x1 * (2 * x1 - 1)) / 6
    size = len(table)
    total = np.bincount(row, n, size)
    mx = np.bincount(row, sx, size) / total
    my = np.bincount(row, n * y, size) / total
    var_x = np.bincount(row, sxx, size) / total - mx * mx
    var_y = np.bincount(row, n * y * y, size) / total - my * my
    cov = np.bincount(row, sx * y, size) / total - mx * my
    x, y0 = table.x1 + mx, table.y1 + my
    return SpotMoments(x, y0, var_x, var_y, cov, var_x, var_y, cov)


#: Most window pixels whose moment terms are held at once (about 100 bytes each): larger
#: sets of windows, and windows larger than this, are summed in pieces of rows, so that
#: memory stays bounded whatever the image holds (a frame-sized glare, thousands of blobs).
WINDOW_CHUNK_PX = 1 << 19


@dataclass(frozen=True)
class _Windows:
    """Each group's window: left column, top row, columns and rows."""

    x0: NDArray[np.int64]
    y0: NDArray[np.int64]
    ncol: NDArray[np.int64]
    nrow: NDArray[np.int64]


@dataclass(frozen=True)
class _Spot:
    """What the window sums read besides the windows."""

    image: NDArray
    white: NDArray[np.bool_]
    grouping: Grouping
    table: GroupTable
    background: Background
    pixel_aspect: float
    #: the stacked frames and each table row's frame (None, None: one frame)
    stacked: tuple[Frames | None, NDArray[np.int64] | None]


def _chunked_sums(spot: _Spot, win: _Windows) -> NDArray[np.float64]:
    """:func:`_window_sums` of every window, in pieces of at most :data:`WINDOW_CHUNK_PX`
    pixels (a window larger than that is cut into bands of rows), added up per window."""
    band = np.maximum(WINDOW_CHUNK_PX // win.ncol, 1)  # rows per piece
    pieces = -(-win.nrow // band)
    group = np.arange(len(win.nrow)).repeat(pieces)
    k = np.arange(group.size) - (pieces.cumsum() - pieces).repeat(pieces)
    start = k * band[group]  # first window row of each piece
    rows = np.minimum(band[group], win.nrow[group] - start)
    area = rows * win.ncol[group]
    # consecutive pieces, at most WINDOW_CHUNK_PX pixels together (or one larger piece)
    chunk = np.floor_divide(area.cumsum() - area, WINDOW_CHUNK_PX)
    cuts = np.flatnonzero(np.diff(chunk)) + 1
    parts = [
        _window_sums(spot, win, group[a:b], start[a:b], rows[a:b])
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, group.size], strict=True)
    ]
    sums = np.concatenate(parts, axis=2)
    return np.add.reduceat(sums, pieces.cumsum() - pieces, axis=2)


def _window_sums(
    spot: _Spot,
    win: _Windows,
    group: NDArray[np.int64],
    start: NDArray[np.int64] | int,
    rows: NDArray[np.int64],
) -> NDArray[np.float64]:
    """Raw window and core sums ``(window | core, term, piece)`` of pieces of windows.

    Piece ``i`` is rows ``start[i]`` to ``start[i] + rows[i] - 1`` of the window of table
    row ``group[i]``; its terms are taken about the whole window's corner, so that the
    pieces of one window add up to the window's sums.
    """
    image, table, grouping = spot.image, spot.table, spot.grouping
    width = image.shape[1]
    ncol = win.ncol[group]
    area = ncol * rows
    first = area.cumsum() - area
    # Every piece's pixels, piece after piece, each in scan order: each piece's lines,
    # then each line's pixels, by repeats (an integer divmod per pixel cost six times more)
    line = np.arange(group.size).repeat(rows)
    line_row = np.arange(line.size) - (rows.cumsum() - rows)[line]
    line_cols = ncol[line]
    g = line.repeat(line_cols)
    row = line_row.repeat(line_cols)
    col = np.arange(g.size) - (line_cols.cumsum() - line_cols).repeat(line_cols)
    row += np.asarray(start).repeat(area) if np.ndim(start) else start
    t = group[g]  # table row of each pixel
    corner = win.y0 * width + win.x0
    frames, frame = spot.stacked
    if frames is not None and frame is not None:  # each group at its frame's rows
        corner = corner + frame * (frames.stride * width)
    flat = corner[t] + row * width + col
    own = _own_pixels(spot, win, group, start, rows, first, g.size)
    # Raw moments about each window's corner (small numbers: no cancellation) of the
    # window's weights and of its own pixels' weights (core), all in one segment
    # reduction since each piece's pixels are contiguous. Terms 1, x, y, x^2, y^2, xy,
    # each product taken as (w x) x etc. so that the sums stay those of w * x * x, and
    # written in place: the terms are most of the pixel-level work.
    terms = np.empty((6, 2, g.size))
    weight = terms[0, 0]
    if image.dtype == np.bool_:
        weight[:] = own
    else:
        bg = background_at(spot.background, flat, None if frame is None else frame[t])
        np.subtract(image.ravel().take(flat), bg, out=weight, dtype=np.float64)
        weight[spot.white.ravel().take(flat) & ~own] = 0.0
    split = (~np.isnan(grouping.centre_x[table.label])).nonzero()[0]
    if split.size:
        xs, ys = win.x0[t] + col, win.y0[t] + row
        weight *= _nearest_part_mask(t, xs, ys, split, grouping, table, spot.pixel_aspect)
    np.multiply(weight, own, out=terms[0, 1])
    w = terms[0]
    np.multiply(w, col, out=terms[1])
    np.multiply(w, row, out=terms[2])
    np.multiply(terms[1], col, out=terms[3])
    np.multiply(terms[2], row, out=terms[4])
    np.multiply(terms[1], row, out=terms[5])
    if g.size == 0:
        return np.zeros((2, 6, group.size))
    return np.add.reduceat(terms, first, axis=2).transpose(1, 0, 2)


#: The centroid coordinates (x, y) whose products make the central terms x^2, y^2, xy.
_LEFT = np.array([0, 1, 0])
_RIGHT = np.array([0, 1, 1])


def _own_pixels(
    spot: _Spot,
    win: _Windows,
    group: NDArray[np.int64],
    start: NDArray[np.int64] | int,
    rows: NDArray[np.int64],
    first: NDArray[np.int64],
    size: int,
) -> NDArray[np.bool_]:
    """Which pixels of the pieces are white pixels of the window's own group.

    Each run lies inside its group's window, so its pixels are scattered straight to
    their piece positions: no image-sized owner map to clear and look up. With pieces
    (not every window whole) the runs are those of the pieces' rows.
    """
    runs, table = spot.grouping.runs, spot.table
    row = table.label.searchsorted(runs.group)
    if np.ndim(start) or group.size != len(table):
        runs, row, piece = _piece_runs(runs, row, win, group, np.asarray(start), rows)
    else:
        piece = row
    ncol = win.ncol[row]
    # position of image pixel (x, y) in piece i: first + (y - y0 - start) ncol + (x - x0)
    top = win.y0[row] + (np.asarray(start)[piece] if np.ndim(start) else start)
    offset = first[piece] - top * ncol - win.x0[row] + runs.y * ncol + runs.x1
    count = runs.x2 - runs.x1 + 1
    end = count.cumsum()
    own = np.zeros(size, dtype=bool)
    pixels = int(end[-1]) if end.size else 0
    own[np.arange(pixels) + (offset - end + count).repeat(count)] = True
    return own


def _piece_runs(
    runs: Runs,
    row: NDArray[np.int64],
    win: _Windows,
    group: NDArray[np.int64],
    start: NDArray[np.int64],
    rows: NDArray[np.int64],
) -> tuple[Runs, NDArray[np.int64], NDArray[np.int64]]:
    """The runs lying in the given pieces of windows: the runs, their table rows and the
    piece each lies in. Pieces are in (table row, first row) order and do not overlap."""
    height = int(win.y0.max() + win.nrow.max()) + 1
    key = row * height + (runs.y - win.y0[row])
    order = np.argsort(key, kind="stable")
    lo = key[order].searchsorted(group * height + start)
    hi = key[order].searchsorted(group * height + start + rows)
    count = hi - lo
    pick = order[np.arange(count.sum()) + (lo - count.cumsum() + count).repeat(count)]
    piece = np.arange(group.size).repeat(count)
    return runs.take(pick), row[pick], piece


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

    ``g`` is the table row of each pixel. Each pixel is compared with the centres of its
    part's siblings only, one sibling rank at a time (the first nearest wins ties), so
    memory is linear in the window pixels and time in window pixels times the largest
    family (a few parts: splits never cut a group into more than a handful).
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
    family_of_row = np.full(len(table), -1)
    family_of_row[order] = np.arange(first.size).repeat(count)
    rows = (family_of_row[g] >= 0).nonzero()[0]
    fam = family_of_row[g[rows]]
    px, py = xs[rows], ys[rows]
    best = np.full(rows.size, np.inf)
    nearest = np.full(rows.size, -1)
    label = table.label
    for rank in range(int(count.max())):
        has = (count[fam] > rank).nonzero()[0]
        sibling = order[first[fam[has]] + rank]
        lab = label[sibling]
        d = ((px[has] - grouping.centre_x[lab]) / pixel_aspect) ** 2
        d += (py[has] - grouping.centre_y[lab]) ** 2
        d /= grouping.radius[lab] ** 2
        closer = d < best[has]
        at = has[closer]
        best[at] = d[closer]
        nearest[at] = sibling[closer]
    keep[rows] = nearest == g[rows]
    return keep
