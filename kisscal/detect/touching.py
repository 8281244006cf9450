"""Touching markers: one group per marker by the peaks of the distance transform.

Not in Shafiq et al. 2001. Its overlap (ul/ur) and long/wide tests cut a group into two, or into
equal parts along one axis; a cluster of three markers that touch (foot markers seen
along the foot) defeats both. Markers that touch, or overlap by less than about half a
radius, leave a neck between them: inside the group's white pixels, the distance to the
background then has one peak per marker. The group is stretched vertically by the pixel
aspect first so that distances are round, and each peak's height is its marker's radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import Grouping, split_groups
from kisscal.detect.groups import GroupTable, group_canvas
from kisscal.detect.params import DetectionParams

NECK = 0.8  # a neck is lower than this fraction of the lower of the two peaks
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
    ridges = _Ridges.of(crop, np.zeros(1, np.int64), pixel_aspect)
    return ridges.peaks(np.zeros(1, np.int64), pixel_aspect, min_separation)[0]


@dataclass(frozen=True)
class _Ridges:
    """The distance transform of stacked crops (:func:`~kisscal.detect.groups.
    group_canvas`, rows repeated ``stretch`` times) and its ridges: the connected sets
    of local maxima at least half their crop's highest value. One distance transform,
    maximum filter and labelling for all the crops instead of one per crop: on real
    frames hundreds of irregular groups are examined. Each ridge's crop, mean ``x, y``
    in its crop's (unstretched) pixels and height, the ridges of each crop in the order
    labelling numbers them alone."""

    dist: NDArray[np.float32]
    top: NDArray[np.int64]  # first canvas row of each crop (stretched)
    stretch: int
    crop: NDArray[np.int64]
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    height: NDArray[np.float64]

    @classmethod
    def of(cls, canvas: NDArray[np.uint8], top: NDArray[np.int64], pixel_aspect: float) -> _Ridges:
        stretch = max(round(pixel_aspect), 1)
        if stretch > 1:
            canvas, top = np.repeat(canvas, stretch, axis=0), top * stretch
        dist = cv2.distanceTransform(canvas, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        row_crop = np.searchsorted(top, np.arange(canvas.shape[0]), side="right") - 1
        highest = np.maximum.reduceat(dist.max(axis=1), top)
        ridge = (dist >= cv2.dilate(dist, np.ones((3, 3), np.uint8))) & (
            dist >= 0.5 * highest[row_crop][:, None]
        )
        ridge &= dist > 0
        n, labels = cv2.connectedComponents(ridge.astype(np.uint8), connectivity=8)
        ys, xs = np.nonzero(labels)
        ridge_of = labels[ys, xs] - 1
        count = np.bincount(ridge_of, minlength=n - 1).astype(float)
        crop = np.zeros(n - 1, np.int64)
        crop[ridge_of] = row_crop[ys]
        height = np.zeros(n - 1, np.float32)
        np.maximum.at(height, ridge_of, dist[ys, xs])
        # the sums of whole pixel indices are exact: the crop's offset comes off before
        # the division, so each mean is the one of the crop alone
        sum_y = np.bincount(ridge_of, ys, n - 1) - count * top[crop]
        x = np.bincount(ridge_of, xs, n - 1) / count
        y = (sum_y / count + 0.5) / stretch - 0.5
        return cls(dist, top, stretch, crop, x, y, height.astype(float))

    def peaks(
        self, crops: NDArray[np.int64], pixel_aspect: float, min_separation: float
    ) -> list[NDArray[np.float64]]:
        """:func:`marker_peaks` of each crop of ``crops``: every pair of a crop's ridges
        is judged at once (apart, with a neck between them), then each crop keeps its
        ridges highest first that stand apart from every ridge kept before them."""
        order = np.lexsort((-self.height, self.crop))  # by crop, highest first (stable)
        first = np.searchsorted(self.crop[order], crops)
        count = np.searchsorted(self.crop[order], crops, side="right") - first
        ok = self._apart(order, first, count, pixel_aspect, min_separation)
        out, at = [], 0
        for start, c in zip(first.tolist(), count.tolist(), strict=True):
            apart = ok[at : at + c * c].reshape(c, c)  # [kept before, candidate]
            at += c * c
            kept: list[int] = []
            for j in range(c):
                if apart[kept, j].all():
                    kept.append(j)
            ids = order[start + np.asarray(kept, dtype=np.int64)]
            out.append(np.column_stack([self.x[ids], self.y[ids], self.height[ids] / pixel_aspect]))
        return out

    def _apart(
        self,
        order: NDArray[np.int64],
        first: NDArray[np.int64],
        count: NDArray[np.int64],
        pixel_aspect: float,
        min_separation: float,
    ) -> NDArray[np.bool_]:
        """For every ordered pair (i, j) of each crop's ridges (crop after crop, i-major),
        whether candidate j stands apart from i: further than ``min_separation`` times
        the higher's height (in scan lines: x over the aspect) and with the distance
        transform between them dropping below ``NECK`` times the lower's height."""
        size = count * count
        crop = np.arange(count.size).repeat(size)
        p = np.arange(crop.size) - (size.cumsum() - size)[crop]
        b = order[first[crop] + p // count[crop]]  # the ridge kept before
        a = order[first[crop] + p % count[crop]]  # the candidate
        x, y, h = self.x, self.y, self.height
        far = np.hypot((x[a] - x[b]) / pixel_aspect, y[a] - y[b])
        far = far > min_separation * np.maximum(h[a], h[b]) / pixel_aspect
        xs = np.rint(x[a][:, None] + _ALONG * (x[b] - x[a])[:, None]).astype(np.intp)
        ys = (y[a][:, None] + _ALONG * (y[b] - y[a])[:, None] + 0.5) * self.stretch - 0.5
        ys = np.rint(ys).astype(np.intp)
        top = self.top[self.crop[a]]
        bottom = np.append(self.top[1:], self.dist.shape[0])[self.crop[a]]
        np.clip(ys, 0, (bottom - top - 1)[:, None], out=ys)
        neck = self.dist[ys + top[:, None], xs].min(axis=1, initial=np.inf)
        return far & (neck < NECK * np.minimum(h[a], h[b]))


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
    if idx.size == 0:
        return grouping
    ridges = _Ridges.of(*group_canvas(grouping.runs, table, idx), params.pixel_aspect)
    # only crops with two ridges or more can hold two peaks: a few per image
    several = np.flatnonzero(np.bincount(ridges.crop, minlength=idx.size) >= 2)
    found = ridges.peaks(several, params.pixel_aspect, params.touching_separation)
    # more peaks than a cluster of markers holds: a bright region, left whole
    keep = [k for k, peaks in enumerate(found) if 2 <= len(peaks) <= params.split_max_markers]
    rows, found = idx[several[keep]], [found[k] for k in keep]
    labels = table.label[rows]
    for i, peaks in zip(rows, found, strict=True):
        peaks[:, 0] += table.x1[i] - 1
        peaks[:, 1] += table.y1[i] - 1
    if not found:
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
