"""Spots inside oversized groups: bright cores told from the dim region they touch.

Not in Shafiq et al. (2001). On real frames a marker or target dot often touches a
dimmer region at the threshold: a glare halo around it, a lit wall or window frame behind
it, a comet tail or a reflected ghost beside it. The union is larger than any marker and
the size limits (section 2.3.4) would drop the marker with it. Its pixels, though, stand
out of the dim region by their grey level. Within each oversized group a second threshold
relative to the group itself, half-way from the group's own median level to its peak (the
half-maximum of the brightest spot it holds), and at least the threshold's contrast above
that median, keeps the bright cores; each core of a marker's size becomes a group of its
own (flag ``detached``), and the rest stays one oversized group (``too_large``), provided
it is still larger than a marker without them (two or three touching markers leave only
their rims, and the split tests separate them).
A uniformly bright region (an LED ring, a lit surface) has no such core of a marker's
size and is left as it was.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal.detect import blobs as fl
from kisscal.detect.advanced import Grouping, group_pixels, oversized, regroup
from kisscal.detect.groups import GroupTable, group_crops
from kisscal.detect.params import DetectionParams

#: The cut between a group's median and its peak (0.5: half maximum).
CORE_LEVEL = 0.5
#: Most cores of one oversized group: more are the texture of a lit surface, left whole.
MOST_CORES = 16


def detach_cores(
    grouping: Grouping,
    table: GroupTable,
    image: NDArray,
    background: float | NDArray[np.floating],
    params: DetectionParams,
) -> Grouping:
    """Separate the marker-sized bright cores of oversized groups from them (see module).

    Parameters
    ----------
    grouping, table : Grouping, GroupTable
        The groups after noise removal and the LED-ring detach.
    image : ndarray
        The grey image.
    background : float or ndarray
        Background level, one value or a map of the image's shape.
    params : DetectionParams
        Size limits (a core must be within them and hold ``min_pixels``) and threshold.

    Returns
    -------
    Grouping
        Each oversized group with cores replaced by its cores and its remainder.
    """
    big = oversized(table, params).nonzero()[0]
    if big.size == 0 or image.dtype == np.bool_:
        return grouping
    contrast = params.threshold
    if not params.background_tile_px:
        contrast -= float(np.mean(background))
    found: dict[int, tuple[NDArray[np.int32], int, int]] = {}
    for i, x0, y0, crop in group_crops(grouping.runs, table, big):  # a few per image
        cores = _cores(crop, image, background, x0, y0, max(contrast, 1.0), params)
        if cores is not None:
            found[i] = (cores, x0, y0)
    if not found:
        return grouping
    rows = np.fromiter(found, dtype=np.int64)
    labels = table.label[rows]
    pixels = group_pixels(grouping, labels)
    part = np.zeros(pixels.x.size, dtype=np.int64)
    k = 1 + max(int(c.max()) for c, _, _ in found.values())
    centres = np.full((3, rows.size, k), np.nan)
    for j, (cores, x0, y0) in enumerate(found.values()):
        mine = (pixels.slot == j).nonzero()[0]
        part[mine] = cores[pixels.y[mine] - y0, pixels.x[mine] - x0]
        n = int(cores.max())
        count = np.bincount(part[mine], minlength=n + 1)[1:]
        centres[0, j, 1 : n + 1] = np.bincount(part[mine], pixels.x[mine], n + 1)[1:] / count
        centres[1, j, 1 : n + 1] = np.bincount(part[mine], pixels.y[mine], n + 1)[1:] / count
        centres[2, j, 1 : n + 1] = np.sqrt(count / (np.pi * params.pixel_aspect))
    centres[2] = np.where(np.isnan(centres[2]), 1.0, centres[2])
    out = regroup(grouping, labels, pixels, part, np.full(rows.size, fl.DETACHED), centres)
    rest = grouping.flags.size + np.arange(rows.size) * k  # part 0 of each: the region
    out.flags[rest] |= fl.TOO_LARGE
    return out


def _cores(
    crop: NDArray[np.uint8],
    image: NDArray,
    background: float | NDArray[np.floating],
    x0: int,
    y0: int,
    contrast: float,
    params: DetectionParams,
) -> NDArray[np.int32] | None:
    """Label map of the crop: 0 the region, 1.. its marker-sized bright cores; None: none."""
    h, w = crop.shape
    ys0, xs0 = max(y0, 0), max(x0, 0)
    window = np.zeros((h, w), np.float32)
    sub = image[ys0 : y0 + h, xs0 : x0 + w].astype(np.float32)
    if np.ndim(background):
        sub -= background[ys0 : y0 + h, xs0 : x0 + w]
    else:
        sub -= np.float32(background)
    window[ys0 - y0 : ys0 - y0 + sub.shape[0], xs0 - x0 : xs0 - x0 + sub.shape[1]] = sub
    inside = crop.astype(bool)
    values = window[inside]
    median = float(np.median(values))
    peak = float(values.max())
    cut = max(median + contrast, median + CORE_LEVEL * (peak - median))
    if peak < cut:
        return None
    bright = (inside & (window >= cut)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(bright, connectivity=8)
    area = stats[1:, cv2.CC_STAT_AREA]
    ok = (area >= max(params.min_pixels, 2)) & (stats[1:, cv2.CC_STAT_WIDTH] >= 2)
    ok &= stats[1:, cv2.CC_STAT_HEIGHT] >= 2
    for limit, column in (
        (params.max_pixels, area),
        (params.max_width_px, stats[1:, cv2.CC_STAT_WIDTH]),
        (params.max_height_px, stats[1:, cv2.CC_STAT_HEIGHT]),
    ):
        if limit is not None:
            ok &= column <= limit
    if not ok.any() or ok.sum() > MOST_CORES:
        return None
    # a region with cores on it stays larger than a marker without them; a pair or
    # cluster of markers does not (its rims are all that is left): the split tests
    # take those
    if params.max_pixels is not None and values.size - area[ok].sum() <= params.max_pixels:
        return None
    number = np.zeros(n, dtype=np.int32)
    number[1:][ok] = np.arange(1, int(ok.sum()) + 1, dtype=np.int32)
    return number[labels]
