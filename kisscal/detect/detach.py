"""Markers touching an LED ring, separated from it before the size limits.

Not in Shafiq et al. 2001, where such a marker is lost inside the invalid LED group. The
oversized groups of an image (LED rings of facing cameras: a few per image, in most
images) are opened, dilated and labelled together on one canvas
(:func:`~kisscal.detect.groups.group_canvas`), so that the common case, rings with
nothing attached, costs a handful of OpenCV calls per image rather than per ring.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import Grouping, oversized, split_groups
from kisscal.detect.groups import GroupTable, group_canvas
from kisscal.detect.params import DetectionParams

#: One LED ring's parts: ``(x, y, radius)`` of its opened core first, then of each piece.
Parts = list[tuple[float, float, float]]


def detach_from_large(
    grouping: Grouping,
    table: GroupTable,
    params: DetectionParams,
    shape: tuple[int, ...] | None = None,
    stride: int | None = None,
) -> Grouping:
    """Separate markers touching an oversized blob (an LED ring) before the size limits.

    The group's white pixels are opened with an elliptical kernel of ``detach_kernel_px``
    (larger than any marker, smaller than an LED ring): what the opening removes and does
    not border the opened blob is a marker sticking out of it when it has at least
    ``detach_min_pixels`` (and ``min_pixels``) pixels and does not touch the border of an
    image of ``shape`` (the opening leaves slivers in the corners of a ring the border
    cuts), provided the opened blob alone still has more than ``max_pixels`` pixels. The
    group is then split between the blob and those markers by distance relative to each
    one's size (:func:`~kisscal.detect.advanced.split_groups`). With ``stride``, the
    groups are those of frames of ``shape`` stacked every ``stride`` rows, and the border
    is each frame's own.
    """
    if params.detach_kernel_px is None or params.max_pixels is None:
        return grouping
    # an LED ring spans a few markers; glare and lit surfaces spanning much of the
    # image are no ring with markers on it, and their opening would cost the most
    ring_sized = table.width * table.height <= RING_MAX_MARKERS * params.max_pixels
    idx = (oversized(table, params) & ring_sized).nonzero()[0]
    if idx.size == 0:
        return grouping
    kw, kh = map(int, params.detach_kernel_px)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (kw, kh))
    found: dict[int, Parts] = {}
    for part in _canvas_chunks(table, idx, kh):
        found.update(_detach_parts(grouping, table, part, params, (shape, stride), kernel, kh))
    if not found:
        return grouping
    found = dict(sorted(found.items()))  # rings in table order
    k = max(len(p) for p in found.values())
    table_xyr = np.full((len(found), k, 3), np.nan)
    for row, parts in enumerate(found.values()):
        table_xyr[row, : len(parts)] = parts
    radii = np.where(np.isnan(table_xyr[:, :, 2]), 1.0, table_xyr[:, :, 2])
    return split_groups(
        grouping,
        table.label[np.fromiter(found, dtype=np.int64)],
        table_xyr[:, :, 0],
        table_xyr[:, :, 1],
        np.full(len(found), fl.DETACHED),
        params.pixel_aspect,
        radii,
    )


#: An oversized blob whose rectangle holds more than this many of the largest markers
#: is not opened to detach markers from it (glare, a lit surface: no LED ring).
RING_MAX_MARKERS = 64
#: Most pixels of one canvas of oversized groups: more groups are opened in turns.
CANVAS_CHUNK_PX = 1 << 18


def _canvas_chunks(table: GroupTable, idx: NDArray[np.int64], gap: int) -> list[NDArray[np.int64]]:
    """``idx`` in sets whose stacked canvas (rows times the widest crop) stays within
    :data:`CANVAS_CHUNK_PX` (a set of one group may exceed it: its own crop), narrow
    groups together so that one wide glare does not widen every crop."""
    rows = (table.height[idx] + 2 + gap + 1).cumsum()
    if rows[-1] * (int(table.width[idx].max()) + 2) <= CANVAS_CHUNK_PX:
        return [idx]  # the usual image: its few LED rings on one canvas
    idx = idx[np.argsort(table.width[idx], kind="stable")]
    rows = (table.height[idx] + 2 + gap + 1).cumsum()
    width = table.width[idx] + 2
    chunks, begin = [], 0
    for end in range(1, idx.size + 1):  # a few oversized groups per image
        base = rows[begin - 1] if begin else 0
        if end < idx.size and (rows[end] - base) * width[end] > CANVAS_CHUNK_PX:
            chunks.append(idx[begin:end])
            begin = end
    chunks.append(idx[begin:])
    return [np.sort(c) for c in chunks if c.size]


def _detach_parts(
    grouping: Grouping,
    table: GroupTable,
    idx: NDArray[np.int64],
    params: DetectionParams,
    frame: tuple[tuple[int, ...] | None, int | None],
    kernel: NDArray[np.uint8],
    kh: int,
) -> dict[int, Parts]:
    """The parts of the LED rings among the oversized groups ``idx`` (one canvas)."""
    # The opening reaches kh // 2 rows: kh black rows keep each crop's opening its own
    # (and, the ellipse's middle row and column being full, a crop's own black border
    # stops an erosion exactly where the crop's edge would).
    canvas, top = group_canvas(grouping.runs, table, idx, gap=kh)
    core = cv2.morphologyEx(canvas, cv2.MORPH_OPEN, kernel)
    # Only a blob that stays oversized without the pieces is an LED ring; overlapping
    # markers have no such core and are left to the overlap and long/wide tests.
    ring = np.add.reduceat(np.count_nonzero(core, axis=1), top) > params.max_pixels
    if not ring.any():
        return {}
    return _ring_parts(canvas, core, top, ring, table, idx, params, frame)


def _ring_parts(
    canvas: NDArray[np.uint8],
    core: NDArray[np.uint8],
    top: NDArray[np.int64],
    ring: NDArray[np.bool_],
    table: GroupTable,
    idx: NDArray[np.int64],
    params: DetectionParams,
    frame: tuple[tuple[int, ...] | None, int | None],
) -> dict[int, Parts]:
    """The core and the marker-sized pieces of every LED ring that lost pieces to the
    opening, by table row (rings in table order). A ring with more pieces than
    ``split_max_markers`` is left whole.

    A piece is a component of what the opening removed, away from the opened blob.
    Positions are image pixels, each piece's centroid summed over its own pixels so that
    it does not depend on where its crop lies on the canvas.
    """
    residual = canvas & (1 - cv2.dilate(core, np.ones((3, 3), np.uint8)))
    _, labels, stats, cents = cv2.connectedComponentsWithStats(residual, connectivity=8)
    left, above, w, h, area = stats[1:].T
    # size first: most images' rings leave only slivers (nine in ten in the gait trial)
    keep = (area >= max(params.detach_min_pixels, params.min_pixels)) & (w >= 2) & (h >= 2)
    if not keep.any():
        return {}
    crop = top.searchsorted(above, side="right") - 1
    above = above - top[crop]  # rows within the crop
    x0 = table.x1[idx] - 1
    y0 = table.y1[idx] - 1
    keep &= ring[crop]
    shape, stride = frame  # the image's shape; rows between stacked frames, or None
    if shape is not None:  # slivers of a ring cut by the image border
        px, py = x0[crop] + left, y0[crop] + above
        if stride:
            py = py % stride
        keep &= (px > 0) & (py > 0) & (px + w < shape[1]) & (py + h < shape[0])
    # more pieces than a cluster of markers holds: a glare with specks along its edge,
    # not an LED ring with markers on it; left whole (and the cost stays bounded)
    pieces = np.bincount(crop[keep], minlength=idx.size)
    keep &= pieces[crop] <= params.split_max_markers
    found: dict[int, Parts] = {}
    for j in keep.nonzero()[0].tolist():  # the rare pieces, in ring then label order
        c = int(crop[j])
        rows = np.nonzero(labels[top[c] : top[c] + table.height[idx[c]] + 2] == j + 1)[0]
        r = np.sqrt(area[j] / (np.pi * params.pixel_aspect))
        piece = (float(x0[c] + cents[j + 1][0]), float(y0[c] + rows.mean()), float(r))
        if c not in found:
            found[c] = _core_centre(core, top, c, x0[c], y0[c], params)
        found[c].append(piece)
    return {int(idx[c]): parts for c, parts in found.items()}


def _core_centre(
    core: NDArray[np.uint8],
    top: NDArray[np.int64],
    c: int,
    x0: int,
    y0: int,
    params: DetectionParams,
) -> Parts:
    """The opened blob of crop ``c``: its centroid (image pixels) and round radius."""
    bottom = top[c + 1] if c + 1 < top.size else core.shape[0]
    cy, cx = np.nonzero(core[top[c] : bottom])
    r = np.sqrt(cx.size / (np.pi * params.pixel_aspect))
    return [(float(x0 + cx.mean()), float(y0 + cy.mean()), float(r))]
