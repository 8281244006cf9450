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
it is still larger than a marker without them, in pixels or in extent (a dot touching a
dim streak): two or three touching markers leave only their rims, and the split tests
separate them.
A uniformly bright region (an LED ring, a lit surface) has no such core of a marker's
size and is left as it was.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import Grouping, GroupPixels, group_pixels, oversized, regroup
from kisscal.detect.groups import GroupTable
from kisscal.detect.params import DetectionParams
from kisscal.detect.stack import Frames, background_at

#: The cut between a group's median and its peak (0.5: half maximum).
CORE_LEVEL = 0.5
#: A group wider or higher than a marker whose pixels outside its cores outnumber the
#: cores' this many times holds a dim region besides them (a marker's own rim, below
#: half maximum, is under twice its core, and under six times even for small spots on
#: non-square pixels).
REST_SHARE = 6.0


def detach_cores(
    grouping: Grouping,
    table: GroupTable,
    image: NDArray,
    background: float | NDArray[np.floating],
    params: DetectionParams,
    frames: Frames | None = None,
) -> Grouping:
    """Separate the marker-sized bright cores of oversized groups from them (see module).

    Parameters
    ----------
    grouping, table : Grouping, GroupTable
        The groups after noise removal and the LED-ring detach.
    image : ndarray
        The grey image.
    background : float or ndarray
        Background level, one value, a map of the image's shape or one value per frame
        of ``frames``.
    params : DetectionParams
        Size limits (a core must be within them and hold ``min_pixels``) and threshold.
    frames : Frames, optional
        The frames stacked in ``image`` (default: one).

    Returns
    -------
    Grouping
        Each oversized group with cores replaced by its cores and its remainder.
    """
    big = oversized(table, params).nonzero()[0]
    if big.size == 0 or image.dtype == np.bool_:
        return grouping
    labels = table.label[big]
    pixels = group_pixels(grouping, labels)
    # each group at its own frame's rows of the stack, against its frame's background
    frame = np.zeros(big.size, np.int64) if frames is None else frames.of(grouping, table)[big]
    rows = pixels.y if frames is None else pixels.y + (frame * frames.stride)[pixels.slot]
    excess = image[rows, pixels.x].astype(np.float32)
    level = background_at(background, rows * image.shape[1] + pixels.x, frame[pixels.slot])
    if np.ndim(background) == 2:
        excess -= level
    else:  # one level (per frame): a float32 level, as for one frame
        excess -= np.asarray(level, dtype=np.float32)
    contrast: float | NDArray[np.float64] = params.threshold
    if not params.background_tile_px:  # one level per frame
        contrast = contrast - np.asarray(background, dtype=float).reshape(-1)[frame]
    core, count = _cores(pixels, (excess, rows), np.maximum(contrast, 1.0), params)
    # a region with cores on it stays larger than a marker without them; a pair or
    # cluster of markers does not (its rims are all that is left): the split tests
    # take those
    if not count.any():
        return grouping
    keep = (count > 0) & _rest_oversized(pixels, core == 0, big.size, params)
    if not keep.any():
        return grouping
    # the kept groups' pixels come out in the same order again, a subsequence
    part = core[keep[pixels.slot]]
    pixels = group_pixels(grouping, labels[keep])
    n, k = int(keep.sum()), int(count[keep].max()) + 1
    where = pixels.slot * k + part
    size = np.bincount(where, minlength=n * k).astype(float)
    safe = np.maximum(size, 1.0)
    centres = np.stack(
        [
            np.bincount(where, pixels.x, n * k) / safe,
            np.bincount(where, pixels.y, n * k) / safe,
            np.sqrt(safe / (np.pi * params.pixel_aspect)),
        ]
    ).reshape(3, n, k)
    centres[:2, :, 0] = np.nan  # the region shares no rim with its cores
    centres[:2, size.reshape(n, k) == 0] = np.nan
    flag = np.full(n, fl.DETACHED)
    out = regroup(grouping, labels[keep], pixels, part, flag, (centres[0], centres[1], centres[2]))
    out.flags[grouping.flags.size + np.arange(n) * k] |= fl.TOO_LARGE  # part 0: the region
    return out


def _rest_oversized(
    pixels: GroupPixels, rest: NDArray[np.bool_], groups: int, params: DetectionParams
) -> NDArray[np.bool_]:
    """Whether each group's pixels outside its cores still exceed an upper size limit: more
    pixels than a marker, or wider or higher than one while outnumbering the cores'
    pixels :data:`REST_SHARE` times (a dim streak or region a dot touches). The rims left
    by two or three touching markers are fewer than that: the split tests take those."""
    slot = pixels.slot[rest]
    size = np.bincount(slot, minlength=groups)
    over = np.zeros(groups, dtype=bool)
    if params.max_pixels is not None:
        over |= size > params.max_pixels
    wide = np.zeros(groups, dtype=bool)
    for limit, coord in ((params.max_width_px, pixels.x), (params.max_height_px, pixels.y)):
        if limit is None or slot.size == 0:
            continue
        low = np.full(groups, np.iinfo(np.int64).max)
        high = np.full(groups, -1)
        np.minimum.at(low, slot, coord[rest])
        np.maximum.at(high, slot, coord[rest])
        wide |= high - low + 1 > limit
    cores = np.bincount(pixels.slot[~rest], minlength=groups)
    return over | (wide & (size >= REST_SHARE * cores))


def _cores(
    pixels: GroupPixels,
    spot: tuple[NDArray[np.float32], NDArray[np.int64]],
    contrast: NDArray[np.float64],
    params: DetectionParams,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Each pixel's core within its group (0: none, else 1, 2, ...) and each group's
    number of cores: components of the pixels above the group's cut, of marker size.
    ``spot``: each pixel's grey level above the background and its image row (rows of
    stacked frames keep their frames apart); ``contrast`` per group."""
    x, slot = pixels.x, pixels.slot
    excess, y = spot
    groups = int(slot.max()) + 1
    # one sort of (group, grey level) keys: the grey levels are bounded (8- or 16-bit
    # scale), so each group's levels fill its own band of the key
    span = float(np.abs(excess).max()) * 2 + 2
    ranked = np.sort(slot * span + (excess + span / 2))
    size = np.bincount(slot, minlength=groups)
    first = size.cumsum() - size
    offset = np.arange(groups) * span + span / 2
    median = ranked[first + size // 2] - offset
    peak = ranked[first + size - 1] - offset
    cut = median + np.maximum(contrast, CORE_LEVEL * (peak - median))
    bright = excess >= cut[slot]
    bx, by = x[bright], y[bright]
    if bx.size == 0:
        return np.zeros(x.size, dtype=np.int64), np.zeros(groups, dtype=np.int64)
    x0, y0 = int(bx.min()), int(by.min())  # label the bright pixels' box only
    mask = np.zeros((int(by.max()) - y0 + 1, int(bx.max()) - x0 + 1), np.uint8)
    mask[by - y0, bx - x0] = 1
    _, comp, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    label = np.zeros(x.size, dtype=np.int64)
    label[bright] = comp[by - y0, bx - x0]
    area, wide, tall = (
        stats[:, c] for c in (cv2.CC_STAT_AREA, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT)
    )
    ok = (area >= max(params.min_pixels, 2)) & (wide >= 2) & (tall >= 2)
    for limit, column in (
        (params.max_pixels, area),
        (params.max_width_px, wide),
        (params.max_height_px, tall),
    ):
        if limit is not None:
            ok &= column <= limit
    ok[0] = False
    # number the good components 1, 2, ... within each group (components never span two)
    owner = np.full(ok.size, -1)
    owner[label[bright]] = slot[bright]
    good = ok.nonzero()[0]
    good = good[np.argsort(owner[good], kind="stable")]
    per = np.bincount(owner[good], minlength=groups)
    rank = np.zeros(ok.size, dtype=np.int64)
    rank[good] = np.arange(good.size) - (per.cumsum() - per).repeat(per) + 1
    return rank[label], per
