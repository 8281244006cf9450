"""Touching markers: one group per marker by the peaks of the distance transform.

Not in Shafiq et al. 2001. Its overlap (ul/ur) and long/wide tests cut a group into two, or into
equal parts along one axis; a cluster of three markers that touch (foot markers seen
along the foot) defeats both. Markers that touch, or overlap by less than about half a
radius, leave a neck between them: inside the group's white pixels, the distance to the
background then has one peak per marker. The group is stretched vertically by the pixel
aspect first so that distances are round, and each peak's height is its marker's radius.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import Grouping, split_groups
from kisscal.detect.groups import GroupTable, group_canvas, group_crops
from kisscal.detect.params import DetectionParams

NECK = 0.8  # a neck is lower than this fraction of the lower of the two peaks


def _neck(
    dist: NDArray[np.float32], a: tuple[float, float], b: tuple[float, float], stretch: int
) -> float:
    """Lowest distance-transform value on the segment between two peaks (rows stretched)."""
    xs = np.rint(a[0] + _ALONG * (b[0] - a[0])).astype(np.intp)
    ys = np.rint((a[1] + _ALONG * (b[1] - a[1]) + 0.5) * stretch - 0.5).astype(np.intp)
    np.minimum(np.maximum(ys, 0, out=ys), dist.shape[0] - 1, out=ys)
    return float(dist[ys, xs].min())


#: Where the segment between two peaks is sampled for a neck (fractions of its length).
_ALONG = np.linspace(0.0, 1.0, 16)


def marker_peaks(
    crop: NDArray[np.uint8], pixel_aspect: float, min_separation: float
) -> NDArray[np.float64]:
    """Peaks of the distance transform of a group's mask, one per marker.

    Parameters
    ----------
    crop : ndarray of uint8, shape (h, w)
        The group's white pixels (1) with a one-pixel background border.
    pixel_aspect : float
        Width / height of a round marker in pixels: rows are repeated this many times
        (rounded) so that distances are round.
    min_separation : float
        Two peaks count as two markers only when they are further apart than this many
        times the larger of their heights (radii) and the distance transform drops
        between them below ``NECK`` times the lower one (a neck); otherwise they are
        maxima along one marker's ridge.

    Returns
    -------
    ndarray, shape (k, 3)
        ``x, y`` of each peak in crop pixel coordinates and its height (the marker's
        radius in scan lines), highest first.
    """
    stretch = max(round(pixel_aspect), 1)
    tall = np.repeat(crop, stretch, axis=0)
    dist = cv2.distanceTransform(tall, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    top = float(dist.max())
    if top <= 0:
        return np.zeros((0, 3))
    ridge = (dist >= cv2.dilate(dist, np.ones((3, 3), np.uint8))) & (dist >= 0.5 * top)
    n, labels = cv2.connectedComponents(ridge.astype(np.uint8), connectivity=8)
    peaks = []
    for j in range(1, n):  # a handful of maxima per group
        ys, xs = np.nonzero(labels == j)
        height = float(dist[ys, xs].max())
        peaks.append((xs.mean(), (ys.mean() + 0.5) / stretch - 0.5, height))
    peaks.sort(key=lambda p: -p[2])
    kept: list[tuple[float, float, float]] = []
    for x, y, height in peaks:
        # distance in round units (scan lines): x divided by the aspect
        if all(
            np.hypot((x - kx) / pixel_aspect, y - ky)
            > min_separation * max(height, kh) / pixel_aspect
            and _neck(dist, (x, y), (kx, ky), stretch) < NECK * min(height, kh)
            for kx, ky, kh in kept
        ):
            kept.append((x, y, height))
    out = np.array(kept, dtype=float).reshape(-1, 3)
    out[:, 2] /= pixel_aspect  # x-pixel units to scan lines (round units)
    return out


def _several_maxima(
    grouping: Grouping, table: GroupTable, idx: NDArray[np.int64], stretch: int = 1
) -> NDArray[np.bool_]:
    """Which of the groups ``idx`` have two or more ridges of high distance-transform
    values, the only ones :func:`marker_peaks` can find two peaks in.

    One distance transform, maximum filter and labelling on a canvas of all the groups
    (:func:`~kisscal.detect.groups.group_canvas`: each crop gets what it would alone)
    instead of one per group: on real frames hundreds of irregular groups are examined
    and nearly all have a single ridge. Rows are repeated ``stretch`` times, as
    :func:`marker_peaks` repeats each crop's (each crop's border rows stay its own).
    """
    canvas, top = group_canvas(grouping.runs, table, idx)
    if stretch > 1:
        canvas, top = np.repeat(canvas, stretch, axis=0), top * stretch
    dist = cv2.distanceTransform(canvas, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    crop = np.searchsorted(top, np.arange(canvas.shape[0]), side="right") - 1
    highest = np.maximum.reduceat(dist.max(axis=1), top)
    ridge = (dist >= cv2.dilate(dist, np.ones((3, 3), np.uint8))) & (
        dist >= 0.5 * highest[crop][:, None]
    )
    ridge &= dist > 0
    n, _, stats, _ = cv2.connectedComponentsWithStats(ridge.astype(np.uint8), connectivity=8)
    first_row = stats[1:n, cv2.CC_STAT_TOP]
    count = np.bincount(crop[first_row], minlength=idx.size)
    return count >= 2


def split_touching(
    grouping: Grouping,
    table: GroupTable,
    params: DetectionParams,
    candidates: NDArray[np.bool_],
) -> Grouping:
    """Split candidate groups with several distance-transform peaks into one per marker.

    Each part is centred on its peak and gets the pixels nearest to it relative to the
    peak's height (its radius), so that markers of different sizes share the neck
    fairly; parts are flagged ``split_touching``.
    """
    idx = candidates.nonzero()[0]
    if idx.size:
        idx = idx[_several_maxima(grouping, table, idx, max(round(params.pixel_aspect), 1))]
    if idx.size == 0:
        return grouping
    labels, found = [], []
    for i, x0, y0, crop in group_crops(grouping.runs, table, idx):  # a few groups per image
        peaks = marker_peaks(crop, params.pixel_aspect, params.touching_separation)
        # more peaks than a cluster of markers holds: a bright region, left whole
        if 2 <= len(peaks) <= params.split_max_markers:
            peaks[:, 0] += x0
            peaks[:, 1] += y0
            labels.append(table.label[i])
            found.append(peaks)
    if not labels:
        return grouping
    k = max(len(p) for p in found)
    packed = np.full((len(labels), k, 3), np.nan)
    for row_index, peaks in enumerate(found):
        packed[row_index, : len(peaks)] = peaks
    radii = np.where(np.isnan(packed[:, :, 2]), 1.0, np.maximum(packed[:, :, 2], 0.5))
    return split_groups(
        grouping,
        np.asarray(labels, dtype=np.int64),
        packed[:, :, 0],
        packed[:, :, 1],
        np.full(len(labels), fl.SPLIT_TOUCHING),
        params.pixel_aspect,
        radii,
    )
