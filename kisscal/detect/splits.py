"""The split tests of one image's groups: touching markers, overlapped pairs (Shafiq et
al. 2001, section 2.3.2) and long/wide groups (2.3.3), with the weighted moments they read.

What the tests read of the groups (the image border, the size limits, growth-corrected
moments and the shapes derived from them) is worked out once per set of groups
(:class:`_Facts`) and again only after a test split a group: most images split nothing,
and each fact costs a handful of numpy calls on a dozen groups, where the calls' own
overhead is what counts.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import (
    Grouping,
    long_wide_split,
    overlap_split,
    oversized,
    splittable,
)
from kisscal.detect.appendage import ROUND_ELONGATION, round_outline
from kisscal.detect.centroid import Background, SpotMoments, window_moments
from kisscal.detect.groups import GroupTable, measure_groups
from kisscal.detect.params import DetectionParams
from kisscal.detect.shape import (
    corrected_moments,
    frame_growth,
    frame_medians,
    height_ratio,
    principal_axes,
    spreads,
)
from kisscal.detect.stack import Frames
from kisscal.detect.touching import split_touching

#: Nearest round groups a group's size is compared with (a target dot's neighbours on the
#: plate; in a marker image, the markers around it).
NEIGHBOURS = 4
#: Most white pixels, in medians of its neighbours', of a group that is one spot among its
#: like. Two equal discs a radius apart or more (a pair the tests must cut: its markers'
#: centres are then half a radius or more off the pair's) cover at least 1.61 discs.
LIKE_NEIGHBOURS = 1.5
#: Most elongation excess (major / minor axis - 1), in medians of the frame's round
#: spots' own, of a group that is one spot among its like: outlines as ragged as theirs.
LIKE_ELONGATION = 4.0


@dataclass(frozen=True)
class Spots:
    """What the weighted moments of a grouping need besides the grouping itself."""

    image: NDArray
    white: NDArray[np.bool_]
    background: Background
    params: DetectionParams
    frames: Frames | None = None

    def moments(self, grouping: Grouping, table: GroupTable) -> SpotMoments:
        p = self.params
        return window_moments(
            self.image,
            self.white,
            grouping,
            table,
            p.centroid_margin_x_px,
            p.centroid_margin_y_px,
            self.background,
            p.pixel_aspect,
            splittable(table, p),
            self.frames,
        )


def split_markers(
    grouping: Grouping, table: GroupTable, spots: Spots, params: DetectionParams
) -> tuple[Grouping, GroupTable, SpotMoments]:
    """Touching, overlap (2.3.2) and long/wide (2.3.3) splits; moments after the last one.

    Moments, and the facts the tests derive from them, are recomputed only after a test
    actually split a group. The growth of the image's spots is estimated once, from the
    groups before any split.
    """
    moments = spots.moments(grouping, table)
    if not (params.split_overlaps or params.split_long_wide or params.split_touching):
        return grouping, table, moments
    height = spots.white.shape[0] if spots.frames is None else spots.frames.height
    where = ((height, spots.white.shape[1]), spots.frames)
    facts = _Facts(grouping, table, moments, where, params)
    tests = [
        (params.split_touching, _touching_step),
        (params.split_overlaps, _overlap_step),
        (params.split_long_wide, _long_wide_step),
    ]
    for enabled, test in tests:
        if not enabled:
            continue
        split = test(facts)
        if split is not facts.grouping:
            table = measure_groups(split.runs)
            moments = _moments_after(spots, facts, split, table)
            facts = _Facts(split, table, moments, facts.where, params, facts.growth)
    return facts.grouping, facts.table, facts.moments


def _moments_after(
    spots: Spots, before: _Facts, grouping: Grouping, table: GroupTable
) -> SpotMoments:
    """The moments of ``table``'s groups after a test split some of ``before``'s.

    A group's window sums read the image, the white pixels (a split moves none), its
    own runs and its family's split centres: only the new parts (labels past the old
    ones) and the groups of their families are weighed again; every other group keeps
    its moments, the same sums (the window moments are most of a detection's time).
    """
    new = table.label >= before.grouping.flags.size
    touched = np.zeros(grouping.parent.size, dtype=bool)
    touched[grouping.parent[table.label[new]]] = True
    redo = touched[grouping.parent[table.label]]
    kept = before.table.label.searchsorted(table.label[~redo])  # tables sorted by label
    known = before.table.label[np.minimum(kept, len(before.table) - 1)] == table.label[~redo]
    if redo.all() or not known.all():
        return spots.moments(grouping, table)
    mine = np.zeros(grouping.flags.size, dtype=bool)
    mine[table.label[redo]] = True
    some = spots.moments(
        grouping.relabel(grouping.runs.take(mine[grouping.runs.group])), table.take(redo)
    )
    out = {}
    for name in SpotMoments.__dataclass_fields__:
        column = np.empty(len(table))
        column[~redo] = getattr(before.moments, name)[kept]
        column[redo] = getattr(some, name)
        out[name] = column
    return SpotMoments(**out)


class _Facts:
    """One set of groups and what the split tests read of it, each computed on first use.

    The groups may be those of several frames stacked (``where``: a frame's shape and
    the :class:`~kisscal.detect.stack.Frames`, or None), each in its own frame's
    coordinates: what a test takes from a frame as a whole (its spots' growth, its
    typical marker) is each frame's own.
    """

    def __init__(
        self,
        grouping: Grouping,
        table: GroupTable,
        moments: SpotMoments,
        where: tuple[tuple[int, int], Frames | None],
        params: DetectionParams,
        growth: NDArray[np.float64] | None = None,
    ) -> None:
        self.grouping = grouping
        self.table = table
        self.moments = moments
        self.where = where
        frames = where[1]
        self.count = 1 if frames is None else frames.count
        # each group's frame
        self.frame = (
            np.zeros(len(table), np.int64) if frames is None else frames.of(grouping, table)
        )
        self.params = params
        self.growth = self._image_growth() if growth is None else growth  # per frame

    def _image_growth(self) -> NDArray[np.float64]:
        p = self.params
        sx, sy = spreads(self.moments.core_var_x, self.moments.core_var_y)
        usable = self.inside & (self.table.pixels >= p.long_wide_min_pixels) & ~self.oversized
        frames = (self.frame, self.count)
        aspect, fallback = p.pixel_aspect, p.growth_px
        return frame_growth(sx, sy, usable, frames, aspect, fallback, p.growth_min_groups)

    def _per_frame(self, values: NDArray, among: NDArray[np.bool_], empty: float) -> NDArray:
        """The median of ``values`` over the ``among`` groups of each group's frame."""
        medians = frame_medians(values[among], self.frame[among], self.count, empty)
        return medians[self.frame]

    @cached_property
    def inside(self) -> NDArray[np.bool_]:
        """Groups clear of the image border (a cut-off spot looks long or wide but is one)."""
        height, width = self.where[0]
        t = self.table
        return (t.x1 > 0) & (t.y1 > 0) & (t.x2 < width - 1) & (t.y2 < height - 1)

    @cached_property
    def oversized(self) -> NDArray[np.bool_]:
        return oversized(self.table, self.params)

    @cached_property
    def corrected(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Core moments with pixel area and the image's growth removed."""
        m = self.moments
        growth = self.growth[self.frame]
        return corrected_moments(m.core_var_x, m.core_var_y, m.core_cov_xy, growth)

    @cached_property
    def ratio(self) -> NDArray[np.float64]:
        return height_ratio(self.corrected[0], self.corrected[1], self.params.pixel_aspect)

    @cached_property
    def axes(self) -> tuple[NDArray[np.float64], ...]:
        return principal_axes(*self.corrected, self.params.pixel_aspect)

    @cached_property
    def single_round(self) -> NDArray[np.bool_]:
        """Groups that are one round spot: never split, whatever their size.

        Their spot moments (growth removed, round units) are nearly equal, elongation at
        most :data:`ROUND_ELONGATION`, and their white pixels fill the ellipse of their
        own second moments (a solid disc does; two or three markers side by side, or a
        neck between them, do not). A target's dots, markers seen face on.
        """
        major, minor, _, _ = self.axes
        p = self.params
        outline = round_outline(
            self.grouping.runs, self.table, p.long_wide_min_pixels, p.pixel_aspect
        )
        return outline & (major <= ROUND_ELONGATION**2 * minor)

    @cached_property
    def like_neighbours(self) -> NDArray[np.bool_]:
        """Groups that are one spot among their like, whatever their shape: no larger
        than :data:`LIKE_NEIGHBOURS` times the median of their :data:`NEIGHBOURS` nearest
        round groups (:attr:`single_round`, single spots for sure) and no more elongated
        than :data:`LIKE_ELONGATION` times the frame's round groups' median excess.

        A target's dots seen at an angle or through aberrated optics have ragged,
        elongated outlines the shape tests cut (OpenPTV's one-dot-example splitter views:
        round groups' median elongation 1.12-1.14), while two markers a radius apart or
        more cover at least 1.6 markers like theirs, and where single markers image round
        (median 1.03-1.07 on rendered fields) a pair's elongation (1.4 or more) stands
        out. Size alone cannot say this (the 1.5-marker rule reverted at stop 47): markers
        far from the camera are smaller than the image's typical one, and a marker's
        neighbours need not be its size.
        """
        t, p = self.table, self.params
        out = np.zeros(len(t), dtype=bool)
        round_ = np.flatnonzero(self.single_round & ~self.oversized)
        ask = self.inside & ~self.single_round & (t.pixels >= p.long_wide_min_pixels)
        ask = np.flatnonzero(ask)
        if round_.size < NEIGHBOURS or ask.size == 0:
            return out
        # frames stacked far apart: no group of another frame is ever among the nearest
        span = 2.0 * max(self.where[0])
        xy = np.column_stack([t.x_binary, t.y_binary + 2.0 * span * self.frame])
        dist, near = cKDTree(xy[round_]).query(xy[ask], NEIGHBOURS)
        near = round_[np.minimum(near, round_.size - 1)]
        typical = np.median(t.pixels[near], axis=1)
        major, minor, _, _ = self.axes
        excess = np.sqrt(major / minor) - 1.0
        ragged = LIKE_ELONGATION * self._per_frame(excess, self.single_round, 0.0)
        alike = (excess <= ragged)[ask] & (t.pixels[ask] <= LIKE_NEIGHBOURS * typical)
        out[ask] = alike & (dist <= span).all(axis=1)
        return out

    @cached_property
    def testable(self) -> NDArray[np.bool_]:
        """Groups the overlap and long/wide tests may split.

        Not those cut by the image border, not those too large to be a marker cluster
        (:func:`~kisscal.detect.advanced.splittable`), and not the parts of a
        touching-marker split or markers detached from an LED ring unless they are large
        enough to hold two markers (1.6 times the image's typical marker): a part cut at
        a neck has a flattened side that the shape tests would misread.
        """
        table = self.table
        inside = self.inside & splittable(table, self.params) & ~self.single_round
        inside &= ~self.like_neighbours
        flags = self.grouping.flags[table.label]
        part = (flags & (fl.SPLIT_TOUCHING | fl.DETACHED)) != 0
        if not part.any():
            return inside
        whole = inside & ~part
        typical = self._per_frame(table.pixels, whole, 0.0)
        return inside & (~part | (table.pixels > 1.6 * typical))

    def not_single(self) -> NDArray[np.bool_]:
        """Groups worth the distance-transform test: not shaped or sized like one marker.

        Cheap moment and size checks keep the (per-group) distance transform off the many
        groups that are plainly single markers, and off LED rings (several times a typical
        marker's size).
        """
        pixels = self.table.pixels
        major, minor, _, _ = self.axes
        sized = (pixels >= self.params.long_wide_min_pixels) & self.inside
        marker = sized & ~self.oversized
        typical = self._per_frame(pixels, marker, np.inf)
        ratio = self.ratio
        odd_shape = (ratio < 0.85) | (ratio > 1.18) | (np.sqrt(major / minor) > 1.2)
        # Up to about three typical markers; beyond that a round group is an LED ring.
        clustered = (pixels > 1.6 * typical) & (pixels < 3.5 * typical)
        return sized & (odd_shape | clustered) & (pixels < 3.5 * typical)


def _touching_step(facts: _Facts) -> Grouping:
    candidates = facts.not_single() & splittable(facts.table, facts.params)
    candidates &= ~facts.single_round & ~facts.like_neighbours
    return split_touching(facts.grouping, facts.table, facts.params, candidates)


def _overlap_step(facts: _Facts) -> Grouping:
    core = (facts.moments.x, facts.moments.y, *facts.corrected)
    return overlap_split(
        facts.grouping, facts.table, facts.params, core, facts.testable, facts.axes
    )


def _long_wide_step(facts: _Facts) -> Grouping:
    return long_wide_split(facts.grouping, facts.table, facts.params, facts.ratio, facts.testable)
