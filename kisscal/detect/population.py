"""Which detected groups are the objects of a scene: markers, a target's dots, particles.

The size limits of detection are derived from the objects alone (:mod:`.configure`): not
from the noise specks below them, nor from LED rings, reflections and streaks above them.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.aspect import MIN_SPOTS_FOR_ASPECT
from kisscal.detect.survey import Groups, stationary

#: Two sizes of blob this many times apart in area belong to different populations.
SIZE_GAP = 2.5
#: Fewest places a population of blobs is seen at to be the objects (more than LED rings).
MIN_PLACES = 8
#: Cell (px) within which blobs of a static scene seen in several frames are one place.
PLACE_PX = 4.0


def marker_population(groups: Groups) -> tuple[NDArray[np.bool_], float | None]:
    """Groups that belong to the marker population (not LED rings, reflections, streaks).

    Streaks (fill below a third) are not markers. When enough groups move between the
    surveyed frames, the markers are the moving ones and every group up to the largest of
    them: LED rings and fixed reflections stay put. Otherwise (rods, grid, a calibration
    target: a static scene) the markers are every group up to the top of the largest
    population that is seen at many places (:func:`objects_top`): a target's dots, not
    the noise specks below them, and not the few LED rings above. Returns the mask and
    the size of the largest objects (pixels), moving ones when they move.
    """
    if len(groups) == 0:
        return np.zeros(0, dtype=bool), None
    area = groups.pixels.astype(float)
    compact = groups.fill >= 0.33
    fixed = stationary(groups)
    moving = compact & ~fixed
    if fixed.any() and moving.sum() >= MIN_SPOTS_FOR_ASPECT:
        return compact & (area <= area[moving].max()), objects_top(groups, moving)
    top = objects_top(groups, compact if compact.any() else ~compact)
    return compact & (area <= top), top


def objects_top(groups: Groups, compact: NDArray[np.bool_]) -> float:
    """The largest area of the object population of a static scene.

    Objects (a target's dots, markers, particles) are round blobs seen at many places;
    noise specks are many but small, LED rings of facing cameras and fixed reflections
    large but at few places. Walking down the areas of the round blobs (one per place),
    the top of the objects is the first area with :data:`MIN_PLACES` round blobs or more
    within :data:`SIZE_GAP` below it: the few larger blobs above are not objects. With
    no such crowd, the most numerous population (the one holding the median) is taken.
    """
    ratio = np.maximum(groups.width, groups.height) / np.minimum(groups.width, groups.height)
    round_ = compact & (groups.fill >= 0.6) & (ratio <= 2.5)
    one = groups.take(round_)
    if len(one):
        cells = np.floor(np.column_stack([one.x, one.y]) / PLACE_PX)
        _, first = np.unique(cells, axis=0, return_index=True)
        area = np.sort(one.pixels[first].astype(float))
        crowd = np.arange(area.size) + 1 - np.searchsorted(area, area / SIZE_GAP)
        top = np.flatnonzero(crowd >= MIN_PLACES)
        if top.size:
            return float(area[top[-1]])
    order = np.sort(groups.pixels[compact].astype(float))
    mid = len(order) // 2
    steps = order[mid + 1 :] / order[mid:-1]
    jumps = np.flatnonzero(steps >= SIZE_GAP)
    return float(order[mid + jumps[0]] if jumps.size else order[-1])


def largest_size(values: NDArray) -> float:
    """The size of the largest markers: the 99th percentile (a few merged pairs aside)."""
    return float(np.percentile(values, 99)) if len(values) >= 50 else float(np.max(values))


def odd_size(value: float) -> int:
    """The odd number of pixels (at least 3) at or above ``value``: a kernel's side."""
    n = max(math.ceil(value), 3)
    return n if n % 2 else n + 1
