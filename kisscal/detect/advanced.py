"""Advanced analysis (Shafiq et al. 2001, section 2.3): sub-marker merging, overlap
(ul/ur) splitting, long/wide splitting and marker size limits.

Groups are carried as labelled runs (:class:`Grouping`). Splitting a group creates one new
label per marker centre estimated by the test, and every white pixel of the group goes to
the nearest centre (distance measured with x scaled by the pixel aspect, so that distance
is round for a round marker); runs crossing the boundary are cut there.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

import kisscal.detect.blobs as fl
from kisscal.detect.groups import GroupTable
from kisscal.detect.params import DetectionParams
from kisscal.detect.scan import Runs
from kisscal.detect.shape import principal_axes


@dataclass(frozen=True)
class Grouping:
    """Labelled runs plus per-label bookkeeping (arrays indexed by label).

    ``flags`` holds each label's flag bits; ``parent`` the label it was split from (itself
    when never split); ``centre_x`` / ``centre_y`` the marker centre the split estimated
    (NaN when not split) and ``radius`` its size (scan lines), used to share the blurred
    rim between the parts: a pixel goes to the part with the smallest distance / radius.
    """

    runs: Runs
    flags: NDArray[np.int64]
    parent: NDArray[np.int64]
    centre_x: NDArray[np.float64]
    centre_y: NDArray[np.float64]
    radius: NDArray[np.float64]

    @classmethod
    def start(cls, runs: Runs) -> Grouping:
        n = int(runs.group.max()) + 1 if len(runs) else 0
        nan = np.full(n, np.nan)
        return cls(runs, np.zeros(n, dtype=np.int64), np.arange(n), nan, nan.copy(), np.ones(n))

    def relabel(self, runs: Runs, flags: NDArray[np.int64] | None = None) -> Grouping:
        """The same bookkeeping over new runs (and optionally new flags)."""
        return Grouping(
            runs,
            self.flags if flags is None else flags,
            self.parent,
            self.centre_x,
            self.centre_y,
            self.radius,
        )

    def keep_groups(self, drop_labels: NDArray[np.int64]) -> Grouping:
        """Remove every run of the given labels."""
        dropped = np.zeros(self.flags.size, dtype=bool)
        dropped[drop_labels] = True
        keep = ~dropped[self.runs.group]
        return self.relabel(self.runs.take(keep))


def merge_submarkers(grouping: Grouping, table: GroupTable, params: DetectionParams) -> Grouping:
    """Merge small groups lying (almost) within a larger group's rectangle (section 2.3.1).

    A group is small when it has at most ``submarker_max_pixels`` white pixels and at most
    ``submarker_max_rows`` scan lines. It is merged into the non-small group whose bounding
    rectangle, grown by ``submarker_margin_px``, covers the largest fraction of its own
    rectangle, when that fraction reaches ``submarker_overlap``.
    """
    small = (table.pixels <= params.submarker_max_pixels) & (
        table.rows <= params.submarker_max_rows
    )
    big = ~small
    if not small.any() or not big.any():
        return grouping
    s, best, ok = _submarker_hosts(table, np.flatnonzero(small), np.flatnonzero(big), params)
    if not ok.any():
        return grouping
    target_of = np.arange(grouping.flags.size)
    target_of[table.label[s[ok]]] = table.label[best[ok]]
    flags = grouping.flags.copy()
    flags[table.label[best[ok]]] |= fl.MERGED
    runs = grouping.runs
    merged = Runs(runs.y, runs.x1, runs.x2, target_of[runs.group])
    return grouping.relabel(merged, flags)


def _submarker_hosts(
    table: GroupTable, s: NDArray[np.int64], b: NDArray[np.int64], params: DetectionParams
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
    """For each small group ``s``, the large group of ``b`` whose grown rectangle covers
    the largest fraction of its rectangle (the first such in table order), and whether
    that fraction reaches ``submarker_overlap``.

    Only pairs whose rectangles can meet are compared: the small groups within reach of
    each large one are found in a k-d tree of their centres (reach: the large rectangle's
    half diagonal plus the largest small one's), never a table of every small group
    against every large one.
    """
    m = params.submarker_margin_px
    centre = np.column_stack([table.x1 + table.x2, table.y1 + table.y2]) * 0.5
    half_small = float(np.hypot(table.width[s], table.height[s]).max()) / 2
    reach = np.hypot(table.width[b] + 2 * m, table.height[b] + 2 * m) / 2 + half_small + 1
    near = cKDTree(centre[s]).query_ball_point(centre[b], reach)
    count = np.fromiter(map(len, near), dtype=np.int64, count=len(near))
    si = np.fromiter(itertools.chain.from_iterable(near), dtype=np.int64, count=int(count.sum()))
    bi = np.arange(b.size).repeat(count)
    ps, pb = s[si], b[bi]
    ox = np.minimum(table.x2[ps], table.x2[pb] + m) - np.maximum(table.x1[ps], table.x1[pb] - m)
    oy = np.minimum(table.y2[ps], table.y2[pb] + m) - np.maximum(table.y1[ps], table.y1[pb] - m)
    covered = np.clip(ox + 1, 0, None) * np.clip(oy + 1, 0, None)
    fraction = covered / (table.width[ps] * table.height[ps])
    # per small group: the largest fraction, ties to the first large group in table order
    order = np.lexsort((bi, -fraction, si))
    first = np.ones(order.size, dtype=bool)
    first[1:] = si[order][1:] != si[order][:-1]
    pick = order[first]
    best = np.zeros(s.size, dtype=np.int64)
    frac = np.zeros(s.size)
    best[si[pick]] = pb[pick]
    frac[si[pick]] = fraction[pick]
    return s, best, frac >= params.submarker_overlap


def split_groups(
    grouping: Grouping,
    labels: NDArray[np.int64],
    centres_x: NDArray[np.float64],
    centres_y: NDArray[np.float64],
    flag: NDArray[np.int64],
    pixel_aspect: float,
    radii: NDArray[np.float64] | None = None,
) -> Grouping:
    """Replace each group in ``labels`` by one group per estimated marker centre.

    Parameters
    ----------
    grouping : Grouping
        Current groups.
    labels : ndarray of int, shape (n,)
        Groups to split.
    centres_x, centres_y : ndarray of float, shape (n, k)
        Marker centres for each group, NaN-padded where a group has fewer than k parts.
    flag : ndarray of int, shape (n,)
        Flag bit to set on the parts.
    pixel_aspect : float
        Width / height of a round marker in pixels, for the nearest-centre distance.
    radii : ndarray of float, shape (n, k), optional
        Size of each part (scan lines); distances are divided by it, so a small marker
        touching a large blob takes only the pixels near it. Equal parts when omitted.

    Returns
    -------
    Grouping
        Groups with the split ones replaced; parts are labelled after all existing labels.
    """
    if labels.size == 0:
        return grouping
    pixels = group_pixels(grouping, labels)
    px, py, ps = pixels.x, pixels.y, pixels.slot
    dx = (px[:, None] - centres_x[ps]) / pixel_aspect
    dy = py[:, None] - centres_y[ps]
    k = centres_x.shape[1]
    if radii is None:
        radii = np.ones((labels.size, k))
    dist = np.where(np.isnan(dx), np.inf, (dx * dx + dy * dy) / radii[ps] ** 2)
    part = np.argmin(dist, axis=1)
    return regroup(grouping, labels, pixels, part, flag, (centres_x, centres_y, radii))


@dataclass(frozen=True)
class GroupPixels:
    """The white pixels of some groups, run after run: column, line, which group (index
    into the labels asked for), and the runs of every other group, left as they are."""

    x: NDArray[np.int64]
    y: NDArray[np.int64]
    slot: NDArray[np.int64]
    others: Runs


def group_pixels(grouping: Grouping, labels: NDArray[np.int64]) -> GroupPixels:
    """The pixels of the groups ``labels`` (few: only groups to be split are expanded)."""
    runs = grouping.runs
    slot = np.full(grouping.flags.size, -1)
    slot[labels] = np.arange(labels.size)
    which = slot[runs.group]
    inside = which >= 0
    cut = runs.take(inside)
    count = cut.length
    run_of = np.repeat(np.arange(len(cut)), count)
    px = cut.x1[run_of] + (np.arange(run_of.size) - np.repeat(np.cumsum(count) - count, count))
    return GroupPixels(px, cut.y[run_of], which[inside][run_of], runs.take(~inside))


def regroup(
    grouping: Grouping,
    labels: NDArray[np.int64],
    pixels: GroupPixels,
    part: NDArray[np.int64],
    flag: NDArray[np.int64],
    centres: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
) -> Grouping:
    """Replace each group of ``labels`` by its parts: pixel ``i`` of ``pixels`` goes to
    part ``part[i]`` (0 to k - 1) of its group; ``centres`` are the parts' ``(x, y,
    radius)``, each of shape (n, k) (NaN centre: a part that shares no rim)."""
    centres_x, centres_y, radii = centres
    k = centres_x.shape[1]
    px, py, ps = pixels.x, pixels.y, pixels.slot
    keep = pixels.others
    base = grouping.flags.size
    new_label = base + ps * k + part
    # Back to runs: a new run starts where the label, the line or column contiguity changes.
    brk = np.ones(px.size, dtype=bool)
    brk[1:] = (new_label[1:] != new_label[:-1]) | (py[1:] != py[:-1]) | (px[1:] != px[:-1] + 1)
    starts = np.flatnonzero(brk)
    ends = np.append(starts[1:], px.size) - 1
    parts = Runs(py[starts], px[starts], px[ends], new_label[starts])
    n_new = labels.size * k
    flags = np.concatenate([grouping.flags, np.repeat(grouping.flags[labels] | flag, k)])
    parent = np.concatenate([grouping.parent, np.repeat(grouping.parent[labels], k)])
    centre_x = np.concatenate([grouping.centre_x, centres_x.reshape(n_new)])
    centre_y = np.concatenate([grouping.centre_y, centres_y.reshape(n_new)])
    radius = np.concatenate([grouping.radius, radii.reshape(n_new)])
    # Parts keep scan order within themselves; groups need not be contiguous in Runs.
    merged = Runs(
        np.concatenate([keep.y, parts.y]),
        np.concatenate([keep.x1, parts.x1]),
        np.concatenate([keep.x2, parts.x2]),
        np.concatenate([keep.group, parts.group]),
    )
    return Grouping(merged, flags, parent, centre_x, centre_y, radius)


def overlap_split(
    grouping: Grouping,
    table: GroupTable,
    params: DetectionParams,
    core: tuple[NDArray[np.float64], ...] | None = None,
    inside: NDArray[np.bool_] | None = None,
    axes: tuple[NDArray[np.float64], ...] | None = None,
) -> Grouping:
    """Split ul / ur overlapped pairs (section 2.3.2, equations 4-6).

    A group with WhitePixels / TotalPixels below ``overlap_ratio_max`` is an overlapped
    pair when the mid-points of its top and bottom rows (x_m^u, x_m^l) are further apart
    than half the top row and than ``overlap_shift_px``. Upper-left (ul) when the top row
    lies left of the bottom row, upper-right (ur) otherwise. The two markers are centred at
    x_m^u and x_m^l with widths 2 (x_m^u - brect.x1) and 2 (brect.x2 - x_m^l) (ul; mirrored
    for ur); their heights follow from the widths through ``pixel_aspect`` and they touch
    the top and bottom of the rectangle.

    Small spots overlapping diagonally rarely meet equation (6) (rows are too few for the
    mid-point shift), so with ``core`` moments ``(x, y, var_x, var_y, cov_xy)`` of each
    group's white pixels (corrected for spot growth, :mod:`kisscal.detect.shape`) a group
    also counts as an overlapped pair when its major axis is
    at least ``overlap_angle_deg`` away from both image axes (round units) and its
    elongation reaches ``overlap_min_elongation``. Two equal spots ``D`` apart add
    ``D^2 / 4`` to the major variance, so their centres are the centroid
    ``+- sqrt(major - minor)`` along the major axis.

    Groups where ``inside`` is False (cut by the image border) are left alone: their shape
    is truncated, not overlapped. ``axes`` are the :func:`~kisscal.detect.shape.principal_axes`
    of the ``core`` moments when the caller has them already.
    """
    x_mu = (table.top_x1 + table.top_x2) * 0.5
    x_ml = (table.bottom_x1 + table.bottom_x2) * 0.5
    shift = x_ml - x_mu
    half_top = x_mu - table.top_x1
    big_enough = table.pixels >= params.long_wide_min_pixels
    if inside is not None:
        big_enough &= inside
    eq6 = (
        big_enough
        & (table.fill < params.overlap_ratio_max)
        & (np.abs(shift) > half_top)
        & (np.abs(shift) > params.overlap_shift_px)
        & (table.height >= 3)
    )
    by_moments = np.zeros(len(table), dtype=bool)
    if core is not None:
        mx, my, vx, vy, cxy = core
        if axes is None:
            axes = principal_axes(vx, vy, cxy, params.pixel_aspect)
        major, minor, ux, uy = axes
        angle = np.degrees(np.arctan2(np.abs(uy), np.abs(ux)))
        diagonal = (angle >= params.overlap_angle_deg) & (angle <= 90 - params.overlap_angle_deg)
        by_moments = (
            big_enough & ~eq6 & diagonal & (np.sqrt(major / minor) >= params.overlap_min_elongation)
        )
    pair = eq6 | by_moments
    if params.max_pixels is not None:  # two halves larger than a marker are no pair
        pair &= table.pixels <= 2 * params.max_pixels
    idx = pair.nonzero()[0]
    if idx.size == 0:
        return grouping
    left = table.x1[idx] - 0.5
    right = table.x2[idx] + 0.5
    ul = shift[idx] > 0
    xu, xl = x_mu[idx], x_ml[idx]
    width_u = np.where(ul, 2 * (xu - left), 2 * (right - xu))
    width_l = np.where(ul, 2 * (right - xl), 2 * (xl - left))
    height = table.height[idx].astype(float)
    h_u = np.minimum(width_u / params.pixel_aspect, height)
    h_l = np.minimum(width_l / params.pixel_aspect, height)
    cy_u = table.y1[idx] - 0.5 + h_u / 2
    cy_l = table.y2[idx] + 0.5 - h_l / 2
    if core is not None:
        m = by_moments[idx]
        half_d = np.sqrt(np.maximum(major[idx] - minor[idx], 0.0))
        # the upper centre first; uy >= 0 points down the image
        sign = np.where(uy[idx] >= 0, -1.0, 1.0)
        dx = sign * half_d * ux[idx] * params.pixel_aspect
        dy = sign * half_d * uy[idx]
        xu = np.where(m, mx[idx] + dx, xu)
        xl = np.where(m, mx[idx] - dx, xl)
        cy_u = np.where(m, my[idx] + dy, cy_u)
        cy_l = np.where(m, my[idx] - dy, cy_l)
        ul = np.where(m, xu < xl, ul)
    flag = np.where(ul, fl.SPLIT_UL, fl.SPLIT_UR)
    return split_groups(
        grouping,
        table.label[idx],
        np.column_stack([xu, xl]),
        np.column_stack([cy_u, cy_l]),
        flag,
        params.pixel_aspect,
    )


def long_wide_split(
    grouping: Grouping,
    table: GroupTable,
    params: DetectionParams,
    ratio: NDArray[np.float64],
    inside: NDArray[np.bool_] | None = None,
) -> Grouping:
    """Split long and wide groups into marker-sized parts (section 2.3.3).

    ``ratio`` (h / w, 1 for a round marker, see :func:`kisscal.detect.shape.height_ratio`)
    below ``min_ratio``
    makes a group wide, above ``max_ratio`` long. A wide group of width ``w`` and height
    ``h`` holds markers of diameter ``d = (h - e) * pixel_aspect + e`` columns, with ``e``
    the ``edge_growth_px`` of a thresholded spot; it is cut into ``round(w / d)`` (at
    least 2) markers spread evenly from its left to its right end; a long one likewise
    from top to bottom. The other coordinate of each part is the group's binary centroid.
    A small group (under 1.5 ``long_wide_min_pixels``) shorter than ``split_min_extent``
    diameters along the cut is left whole, and groups where ``inside`` is False (cut by
    the image border) are not tested.
    """
    w = table.width.astype(float)
    h = table.height.astype(float)
    # Parts of an overlapped pair were already cut to marker size by section 2.3.2.
    overlap_part = (grouping.flags[table.label] & (fl.SPLIT_UL | fl.SPLIT_UR)) != 0
    testable = (table.pixels >= params.long_wide_min_pixels) & ~overlap_part
    if inside is not None:
        testable &= inside
    wide = testable & (ratio < params.min_ratio)
    long = testable & (ratio > params.max_ratio)
    idx = (wide | long).nonzero()[0]
    if idx.size == 0:
        return grouping
    is_wide = wide[idx]
    # Diameter of one marker along the split axis, from the group's extent across it: the
    # thresholded extent of a spot is its outline plus about ``edge_growth_px`` (blur and
    # blooming), which does not scale with the pixel aspect.
    g = params.edge_growth_px
    asp = params.pixel_aspect
    diameter = np.where(is_wide, (h[idx] - g) * asp + g, (w[idx] - g) / asp + g)
    diameter = np.maximum(diameter, 1.0)
    extent = np.where(is_wide, w[idx], h[idx])
    # For a small group the shape alone is too noisy: its extent must agree, a group
    # shorter than ``split_min_extent`` marker diameters along the cut is one spot.
    small = table.pixels[idx] < 1.5 * params.long_wide_min_pixels
    agree = ~small | (extent >= params.split_min_extent * diameter)
    if not agree.any():
        return grouping
    idx, is_wide, diameter, extent = idx[agree], is_wide[agree], diameter[agree], extent[agree]
    k = np.maximum(np.floor(extent / diameter + 0.5), 2).astype(np.int64)
    # More parts than a marker cluster holds, or parts larger than a marker: a bright
    # streak, surface or LED ring, left whole for the size limits.
    few = k <= params.split_max_markers
    if params.max_pixels is not None:
        few &= table.pixels[idx] <= k * params.max_pixels
    if not few.any():
        return grouping
    idx, is_wide, diameter, extent, k = idx[few], is_wide[few], diameter[few], extent[few], k[few]
    kmax = int(k.max())
    j = np.arange(kmax)[None, :]
    valid_part = j < k[:, None]
    start = np.where(is_wide, table.x1[idx], table.y1[idx]) - 0.5
    diameter = np.minimum(diameter, extent / k)
    step = (extent - diameter) / (k - 1)
    along = start[:, None] + diameter[:, None] / 2 + j * step[:, None]
    along = np.where(valid_part, along, np.nan)
    across = np.where(is_wide, table.y_binary[idx], table.x_binary[idx])[:, None]
    across = np.where(valid_part, across, np.nan)
    cx = np.where(is_wide[:, None], along, across)
    cy = np.where(is_wide[:, None], across, along)
    flag = np.where(is_wide, fl.SPLIT_WIDE, fl.SPLIT_LONG)
    return split_groups(grouping, table.label[idx], cx, cy, flag, params.pixel_aspect)


def oversized(table: GroupTable, params: DetectionParams) -> NDArray[np.bool_]:
    """Groups over the upper size limits (section 2.3.4): more pixels, wider or higher.

    A limit left unset (None) holds nothing back.
    """
    large = np.zeros(len(table), dtype=bool)
    for limit, size in (
        (params.max_pixels, table.pixels),
        (params.max_width_px, table.width),
        (params.max_height_px, table.height),
    ):
        if limit is not None:
            large |= size > limit
    return large


def splittable(table: GroupTable, params: DetectionParams) -> NDArray[np.bool_]:
    """Groups small enough to be a cluster of markers: at most ``split_max_markers`` of
    the largest marker (``max_pixels``); every group when no size limit is set."""
    if params.max_pixels is None:
        return np.ones(len(table), dtype=bool)
    return table.pixels <= params.split_max_markers * params.max_pixels


def size_flags(table: GroupTable, params: DetectionParams) -> NDArray[np.int64]:
    """Flag bits of the marker size limits (section 2.3.4): oversized groups (LED rings of
    facing cameras) get ``too_large``, undersized ones ``too_small``."""
    small = table.pixels < params.min_pixels
    return np.where(oversized(table, params), fl.TOO_LARGE, 0) | np.where(small, fl.TOO_SMALL, 0)
