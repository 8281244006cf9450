"""Particle images found as OpenPTV finds its targets (Maas 1992; Maas et al. 1993).

Particle-tracking frames hold hundreds to thousands of small spots of every brightness on
a background that is dark but textured (glass walls, glare, streaks). Maas's target
recognition reads them in four steps, each a whole-image operation here:

1. **high-pass**: the mean of a square box around each pixel is subtracted (what is below
   it is zero), so that slow glare and lit walls fall to the noise;
2. **flat threshold**: a pixel is part of a particle image when the high-passed grey
   stands more than ``threshold`` above zero;
3. **regions grown from peaks**: each local maximum above the threshold grows into the
   pixels above it it reaches by 4-connected steps that never enter a pixel (or a pixel
   beside it) more than ``peak_step`` above the one left (Maas's discontinuity): a faint
   spot cannot climb into a bright particle beside it, and the bright one stays a target
   of its own. Maas's region growing reads the image in scan order; here peaks that reach
   one another are one target and a pixel reached from several goes to the faintest
   (:func:`grow_regions`), the same whatever the order. A region larger than a particle
   (the upper size limits) is lit structure, a wall or glare, that particles stand on:
   it is cut at levels a tenth higher each time up to twice the threshold, then twice as
   high each time, until its pieces are particle-sized;
4. **limits and centroids**: regions touching the image border, with fewer pixels than
   ``min_pixels``, narrower or lower than ``peak_min_extent_px``, or with a summed grey
   below ``peak_min_sum_grey`` are dropped (``too_small``; ``too_large`` above the upper
   limits); the centroid weighs each pixel by its high-passed grey above the threshold.

References
----------
Maas, H.-G. (1992). Digitale Photogrammetrie in der dreidimensionalen
Strömungsmesstechnik. Dissertation, ETH Zürich.
Maas, H.-G., Gruen, A., & Papantoniou, D. (1993). Particle tracking velocimetry in
three-dimensional flows. Experiments in Fluids, 15(2), 133-146.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.sparse import csgraph

import kisscal.detect.blobs as fl
from kisscal.detect.blobs import Blobs
from kisscal.detect.params import DetectionParams
from kisscal.errors import InputError

#: Highest level (grey levels above the box mean) a lit region is cut at.
MAX_LEVEL = 255.0
#: Ratio of a lit region's successive cut levels up to twice the threshold (doubling
#: from the threshold lost the particles fainter than that on a wall's rim: 92.9 -> 93.6 %
#: of OpenPTV's cavity cam3 targets; 1.05 finds the same, steps of 1.1 on up to 255 no
#: more, with 90 more wall pieces a frame and three times the cuts); then doubling.
CUT_STEP = 1.1


def highpass(image: NDArray, side: int) -> NDArray[np.float32]:
    """``image`` less the mean of the ``side`` x ``side`` box around each pixel, zero
    where below (Maas et al. 1993)."""
    grey = image.astype(np.float32, copy=False)
    mean = cv2.blur(grey, (side, side), borderType=cv2.BORDER_REPLICATE)
    np.subtract(grey, mean, out=mean)  # in place: one float image less at the peak
    return np.maximum(mean, np.float32(0.0), out=mean)


def regions(
    hp: NDArray[np.float32],
    threshold: float,
    largest: tuple[int | None, int | None, int | None] = (None, None, None),
    step: float = np.inf,
) -> tuple[NDArray, int]:
    """Label image of the particle regions of a high-passed image and their count.

    The regions above ``threshold`` grown from the peaks without climbing more than
    ``step`` (:func:`grow_regions`; infinite: the 4-connected regions). A region larger
    than a particle (``largest``: pixels, width, height; None: no limit) is lit structure
    (a wall, glare): the particles standing on it are its 4-connected pieces above
    levels :data:`CUT_STEP` times higher each cut up to twice the threshold, then twice
    as high, while they are too large. Each cut reads only the pixels of the regions too
    large (their flat indices), never the whole image.
    """
    labels, top, lit = _grow(hp, threshold, step)
    flat, grey, width = labels.reshape(-1), hp.reshape(-1), hp.shape[1]
    lit = lit[flat[lit] > 0]
    inside = lit[_too_large(lit, flat[lit], top + 1, width, largest)[flat[lit]]]
    level, free = threshold, top + 1  # free: the first label not yet used
    while inside.size and level < MAX_LEVEL:
        level = (CUT_STEP if level < 2.0 * threshold else 2.0) * max(level, 1.0)
        core = inside[grey[inside] > level]
        flat[inside] = 0
        piece, n = _pieces(core, width)
        flat[core] = piece + free
        inside = core[_too_large(core, piece, n, width, largest)[piece]]
        free += n
    return _compact(labels, lit)


def _pieces(pixels: NDArray, width: int) -> tuple[NDArray, int]:
    """4-connected pieces of a sorted set of flat pixel indices of an image ``width``
    wide, found by OpenCV in their bounding box: the piece of each pixel, numbered 0..n-1
    as OpenCV numbers them (in the order of their first pixel read row by row), and n."""
    if pixels.size == 0:
        return pixels.astype(np.int32), 0
    rows, cols = np.divmod(pixels, width)
    rows -= rows[0]
    cols -= cols.min()
    box = np.zeros((int(rows[-1]) + 1, int(cols.max()) + 1), np.uint8)
    box[rows, cols] = 1
    n, piece = cv2.connectedComponents(box, connectivity=4)
    return piece[rows, cols] - 1, n - 1


def grow_regions(hp: NDArray[np.float32], threshold: float, step: float) -> tuple[NDArray, int]:
    """Label image of the particle images of a high-passed image, grown from its peaks,
    and their count.

    A pixel above ``threshold`` belongs to the particle image of a local maximum (8
    neighbours) it is reached from by a 4-connected path above the threshold whose every
    step enters a pixel no brighter, nor next to (4 neighbours) a pixel brighter, than
    ``step`` above the pixel it leaves (Maas 1992's discontinuity). Where several peaks
    reach a pixel it goes to the faintest (a faint particle keeps its halo; a bright one
    beside it is what cannot be climbed to); pixels reached from no peak are left out.
    The result does not depend on the order the image is read in (Maas's scan-order
    growth gives a contested pixel to whichever peak it meets first).

    Parameters
    ----------
    hp : ndarray of float32, shape (h, w)
        High-passed image (:func:`highpass`).
    threshold : float
        Grey level a particle image's pixels stand above.
    step : float
        Largest climb of a step (``inf``: the 4-connected regions above the threshold).

    Returns
    -------
    labels : ndarray of int32, shape (h, w)
        0 outside the regions, 1..count inside.
    count : int

    References
    ----------
    Maas, H.-G. (1992). Digitale Photogrammetrie in der dreidimensionalen
    Strömungsmesstechnik. Dissertation, ETH Zürich.
    """
    labels, _, lit = _grow(hp, threshold, step)
    return _compact(labels, lit)


def _grow(hp: NDArray[np.float32], threshold: float, step: float) -> tuple[NDArray, int, NDArray]:
    """:func:`grow_regions`' labels before they are numbered 1..count (the same order,
    with gaps), a label at least the highest, and the flat indices of the pixels above
    the threshold (the labelled ones among them)."""
    mask = hp > threshold
    count, comp = cv2.connectedComponents(mask.view(np.uint8), connectivity=4)
    cross = cv2.dilate(hp, _CROSS, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    lit, pairs = _steps(hp, cross, mask, step)
    del cross, mask  # whole images no longer needed: freed before the growth's own
    part_of = comp.reshape(-1)[lit]
    hard = np.zeros(count, dtype=bool)
    for i, _, forward, back in pairs:
        hard[part_of[i[~(forward & back)]]] = True
    hard[0] = False
    if not hard.any():
        return comp.astype(np.int32, copy=False), count - 1, lit
    inside = hard[part_of]
    owner = _reached(hp, lit, inside, pairs)
    labels = comp.astype(np.int32, copy=False)
    labels.reshape(-1)[lit[inside]] = np.where(owner > 0, owner + count, 0)
    return labels, count + int(owner.max(initial=0)), lit


#: The pixel and its four neighbours.
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def _steps(
    hp: NDArray[np.float32], cross: NDArray[np.float32], mask: NDArray, step: float
) -> tuple[NDArray, list[tuple[NDArray, NDArray, NDArray, NDArray]]]:
    """The flat indices ``lit`` of the pixels above the threshold (``mask``), and their
    horizontal and vertical pairs of neighbours: the place in ``lit`` of each pixel ``a``,
    of its neighbour ``b``, and whether the step a -> b, and b -> a, enters a pixel whose
    cross (``cross``: it and its 4 neighbours) is at most ``step`` above the pixel left."""
    w = hp.shape[1]
    on = mask.reshape(-1)
    lit = np.flatnonzero(on)
    grey, top = hp.reshape(-1)[lit], cross.reshape(-1)[lit]
    beside = np.flatnonzero((np.diff(lit) == 1) & (lit[:-1] % w != w - 1))
    below = np.flatnonzero(lit < on.size - w)
    below = below[on[lit[below] + w]]
    out = []
    for i, j in ((beside, beside + 1), (below, np.searchsorted(lit, lit[below] + w))):
        out.append((i, j, top[j] <= grey[i] + step, top[i] <= grey[j] + step))
    return lit, out


def _reached(
    hp: NDArray[np.float32],
    lit: NDArray,
    inside: NDArray,
    pairs: list[tuple[NDArray, NDArray, NDArray, NDArray]],
) -> NDArray:
    """For the pixels ``lit[inside]``, 1 + the rank (grey, then position) of the faintest
    peak that reaches each along allowed steps (``pairs``, places in ``lit``), 0 where
    none does.

    The allowed steps are a directed graph; its strongly connected parts (pixels that
    reach one another) take their faintest peak, then pass it down the steps between
    parts until nothing changes.
    """
    pixels = lit[inside]  # node k of the graph is pixel pixels[k]
    node = np.cumsum(inside) - 1  # the node of each pixel of lit inside
    src, dst = [], []
    for i, j, forward, back in pairs:
        keep = inside[i]
        a, b = node[i[keep]], node[j[keep]]
        forward, back = forward[keep], back[keep]
        src += [a[forward], b[back]]
        dst += [b[forward], a[back]]
    s, d = np.concatenate(src), np.concatenate(dst)
    graph = sparse.csr_matrix((np.ones(s.size, np.int8), (s, d)), shape=(pixels.size,) * 2)
    parts, part = csgraph.connected_components(graph, directed=True, connection="strong")
    grey = hp.reshape(-1)[pixels]
    ring = cv2.dilate(hp, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT)
    peak = np.flatnonzero(grey >= ring.reshape(-1)[pixels])
    rank = np.empty(peak.size, dtype=np.int64)
    rank[np.lexsort((pixels[peak], grey[peak]))] = np.arange(peak.size)
    key = np.full(parts, np.iinfo(np.int64).max)
    np.minimum.at(key, part[peak], rank)
    _pass_down(key, part[s], part[d])
    key = key[part]
    return np.where(key < peak.size, key + 1, 0)


def _pass_down(key: NDArray, src: NDArray, dst: NDArray) -> None:
    """Lower ``key`` of each node to the least key of the nodes with a path to it (edges
    ``src`` -> ``dst`` between strongly connected parts, a graph without cycles)."""
    cross = src != dst
    if not cross.any():
        return
    edges = np.unique(src[cross] * key.size + dst[cross])
    src, dst = edges // key.size, edges % key.size  # sorted by src, then dst
    order = np.argsort(dst, kind="stable")
    src, dst = src[order], dst[order]
    starts = np.flatnonzero(np.r_[True, dst[1:] != dst[:-1]])
    heads = dst[starts]
    while True:
        least = np.minimum.reduceat(key[src], starts)
        lower = least < key[heads]
        if not lower.any():
            return
        key[heads[lower]] = least[lower]


def _too_large(
    pixels: NDArray,
    label: NDArray,
    count: int,
    width: int,
    largest: tuple[int | None, int | None, int | None],
) -> NDArray:
    """Which of labels 0..count-1 of the flat pixel indices ``pixels``
    (sorted) of an image ``width`` wide are above any of the limits ``largest`` (pixels,
    width, height); a label without pixels never is."""
    most_pixels, most_width, most_height = largest
    big = np.zeros(count, dtype=bool)
    if most_pixels is not None:
        big |= np.bincount(label, minlength=count) > most_pixels
    for limit, coord in ((most_width, pixels % width), (most_height, pixels // width)):
        if limit is not None:
            low = np.full(count, np.iinfo(np.int64).max // 2)
            high = np.full(count, -1)
            np.minimum.at(low, label, coord)
            np.maximum.at(high, label, coord)
            big |= high - low + 1 > limit
    return big


def _compact(labels: NDArray, pixels: NDArray) -> tuple[NDArray, int]:
    """Labels renumbered 1..n in order (0 stays background), and n; ``pixels``: flat
    indices holding every label above 0 (the rest of the image is read as 0)."""
    flat = labels.reshape(-1)[pixels]
    used = np.flatnonzero(np.bincount(flat))
    used = used[used > 0]
    remap = np.zeros(int(used[-1]) + 1 if used.size else 1, dtype=np.int32)
    remap[used] = np.arange(1, used.size + 1, dtype=np.int32)
    out = np.zeros(labels.shape, dtype=np.int32)
    out.reshape(-1)[pixels] = remap[flat]
    return out, int(used.size)


def region_table(
    hp: NDArray[np.float32], labels: NDArray, count: int, threshold: float
) -> dict[str, NDArray]:
    """Pixels, extent, summed grey, border contact and weighted centroid of each region."""
    on = np.flatnonzero(labels)  # row by row, as np.nonzero reads them
    lab = labels.reshape(-1)[on] - 1
    ys, xs = np.divmod(on, labels.shape[1])
    g = hp.reshape(-1)[on].astype(np.float64)
    w = g - threshold
    n = np.bincount(lab, minlength=count)
    sw = np.bincount(lab, w, minlength=count)
    x0 = np.full(count, np.iinfo(np.int64).max)
    y0 = x0.copy()
    x1 = np.full(count, -1)
    y1 = x1.copy()
    np.minimum.at(x0, lab, xs)
    np.minimum.at(y0, lab, ys)
    np.maximum.at(x1, lab, xs)
    np.maximum.at(y1, lab, ys)
    h, wd = hp.shape
    safe = np.maximum(sw, 1e-12)
    return {
        "pixels": n,
        "x": np.bincount(lab, w * xs, minlength=count) / safe,
        "y": np.bincount(lab, w * ys, minlength=count) / safe,
        "xb": np.bincount(lab, xs, minlength=count) / np.maximum(n, 1),
        "yb": np.bincount(lab, ys, minlength=count) / np.maximum(n, 1),
        "w": x1 - x0 + 1,
        "h": y1 - y0 + 1,
        "sum": np.bincount(lab, g, minlength=count),
        "x0": x0,
        "y0": y0,
        "border": (x0 == 0) | (y0 == 0) | (x1 == wd - 1) | (y1 == h - 1),
    }


def detect_peaks(image: NDArray, params: DetectionParams) -> Blobs:
    """Particle images of one checked, oriented grey image (see the module).

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grey image, bright particles (already inverted when dark).
    params : DetectionParams
        ``peak_highpass_px``, ``threshold`` (grey levels above the box mean),
        ``peak_dip``, ``min_pixels``, ``peak_min_extent_px``, ``peak_min_sum_grey`` and
        the upper limits ``max_pixels``, ``max_width_px``, ``max_height_px``.

    Returns
    -------
    Blobs
        One row per region not touching the border, sorted by its top-left corner.

    References
    ----------
    Maas, H.-G., Gruen, A., & Papantoniou, D. (1993). Particle tracking velocimetry in
    three-dimensional flows. Experiments in Fluids, 15(2), 133-146.
    """
    if image.dtype == np.bool_:
        raise InputError('detect: the "peaks" route needs grey images, not thresholded ones')
    hp = highpass(image, int(params.peak_highpass_px))
    largest = (params.max_pixels, params.max_width_px, params.max_height_px)
    labels, count = regions(hp, float(params.threshold), largest, float(params.peak_step))
    if count == 0:
        return Blobs.empty()
    t = region_table(hp, labels, count, float(params.threshold))
    keep = ~t["border"]
    flags = np.zeros(count, dtype=np.int64)
    small = (t["pixels"] < params.min_pixels) | (t["sum"] < params.peak_min_sum_grey)
    small |= np.minimum(t["w"], t["h"]) < params.peak_min_extent_px
    flags[small] |= fl.TOO_SMALL
    large = np.zeros(count, dtype=bool)
    for limit, value in (
        (params.max_pixels, t["pixels"]),
        (params.max_width_px, t["w"]),
        (params.max_height_px, t["h"]),
    ):
        if limit is not None:
            large |= value > limit
    flags[large] |= fl.TOO_LARGE
    rows = np.flatnonzero(keep)
    order = rows[np.lexsort((t["x0"][rows], t["y0"][rows]))]
    return Blobs(
        x_px=t["x"][order],
        y_px=t["y"][order],
        x_binary_px=t["xb"][order],
        y_binary_px=t["yb"][order],
        pixels=t["pixels"][order].astype(np.int64),
        w_px=t["w"][order].astype(np.int64),
        h_px=t["h"][order].astype(np.int64),
        valid=(flags[order] & fl.INVALID_FLAGS) == 0,
        flags=flags[order],
    )
