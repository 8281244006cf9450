"""Per-group measures the tests need: bounding rectangle (Fig. 4), white and total pixels
(equations 4, 5), the first and last row of each group (equation 6) and the binary
centroid (equation 2)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.scan import Runs


@dataclass(frozen=True)
class GroupTable:
    """Measures of each group label present in a :class:`Runs`, sorted by label.

    ``x1, x2, y1, y2`` bound the group (inclusive pixel indices); ``top_x1, top_x2`` and
    ``bottom_x1, bottom_x2`` are the outer boundary pixels of its first and last scan line
    (x_1^1, x_2^1, x_1^n, x_2^n of equation 6).
    """

    label: NDArray[np.int64]
    x1: NDArray[np.int64]
    x2: NDArray[np.int64]
    y1: NDArray[np.int64]
    y2: NDArray[np.int64]
    pixels: NDArray[np.int64]
    rows: NDArray[np.int64]
    sum_x: NDArray[np.float64]
    sum_y: NDArray[np.float64]
    top_x1: NDArray[np.int64]
    top_x2: NDArray[np.int64]
    bottom_x1: NDArray[np.int64]
    bottom_x2: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.label.shape[0])

    # Derived columns are computed once per table (the tests read them many times).
    @cached_property
    def width(self) -> NDArray[np.int64]:
        """Columns covered by the bounding rectangle (w of equation 4)."""
        return self.x2 - self.x1 + 1

    @cached_property
    def height(self) -> NDArray[np.int64]:
        """Scan lines covered by the bounding rectangle (h of equation 4)."""
        return self.y2 - self.y1 + 1

    @cached_property
    def fill(self) -> NDArray[np.float64]:
        """WhitePixels / TotalPixels (equations 5 over 4)."""
        return self.pixels / (self.width * self.height)

    @cached_property
    def x_binary(self) -> NDArray[np.float64]:
        """Binary centroid x (equation 2)."""
        return self.sum_x / self.pixels

    @cached_property
    def y_binary(self) -> NDArray[np.float64]:
        """Binary centroid y (equation 2)."""
        return self.sum_y / self.pixels

    def take(self, rows: NDArray[np.int64] | NDArray[np.bool_]) -> GroupTable:
        """The measures of some groups: what :func:`measure_groups` gives for their runs
        alone, since every measure is a group's own."""
        return GroupTable(**{f.name: getattr(self, f.name)[rows] for f in fields(self)})


def measure_groups(runs: Runs) -> GroupTable:
    """Measure every group of ``runs`` with segment reductions over runs sorted by group.

    Runs arrive in scan order; a stable sort by group keeps each group's runs in line
    order, so its first and last runs lie in its top and bottom scan lines.
    """
    order = runs.group.argsort(kind="stable")
    g = runs.group[order]
    y = runs.y[order]
    x1 = runs.x1[order]
    x2 = runs.x2[order]
    if g.size == 0:
        e = np.zeros(0, dtype=np.int64)
        f = np.zeros(0, dtype=float)
        return GroupTable(e, e, e, e, e, e, e, f, f, e, e, e, e)
    new_group = _changes(g)
    starts = new_group.nonzero()[0]
    ends = _segment_ends(starts, g.size)
    length = x2 - x1 + 1
    pixels = np.add.reduceat(length, starts)
    # The mean column of a run is its mid-point (equation 3), so a run contributes
    # length * mid-point to the column sum.
    sum_x = np.add.reduceat(length * (x1 + x2) * 0.5, starts)
    sum_y = np.add.reduceat(length * y, starts, dtype=np.float64)  # exact: integer sums
    new_line = new_group | _changes(y)
    line_id = new_line.cumsum() - 1
    line_starts = new_line.nonzero()[0]
    rows = np.add.reduceat(new_line, starts, dtype=np.int64)
    # Runs of one line are sorted by column: its first run holds the left boundary, its
    # last run the right one.
    line_ends = _segment_ends(line_starts, g.size)
    line_x1 = x1[line_starts]
    line_x2 = x2[line_ends]
    top_line = line_id[starts]
    bottom_line = line_id[ends]
    return GroupTable(
        label=g[starts],
        x1=np.minimum.reduceat(x1, starts),
        x2=np.maximum.reduceat(x2, starts),
        y1=y[starts],
        y2=y[ends],
        pixels=pixels,
        rows=rows,
        sum_x=sum_x,
        sum_y=sum_y,
        top_x1=line_x1[top_line],
        top_x2=line_x2[top_line],
        bottom_x1=line_x1[bottom_line],
        bottom_x2=line_x2[bottom_line],
    )


def _changes(values: NDArray[np.int64]) -> NDArray[np.bool_]:
    """True where a sorted segment starts: the first entry and wherever the value changes."""
    out = np.empty(values.size, dtype=bool)
    out[0] = True
    np.not_equal(values[1:], values[:-1], out=out[1:])
    return out


def _segment_ends(starts: NDArray[np.int64], size: int) -> NDArray[np.int64]:
    """Last index of each segment given the segments' first indices."""
    ends = np.empty_like(starts)
    ends[:-1] = starts[1:] - 1
    ends[-1] = size - 1
    return ends


def group_canvas(
    runs: Runs, table: GroupTable, idx: NDArray[np.int64], gap: int = 0
) -> tuple[NDArray[np.uint8], NDArray[np.int64]]:
    """The groups at rows ``idx`` of ``table`` as binary crops stacked in one image.

    Each crop is the group's white pixels with a one-pixel black border (its pixel
    ``(0, 0)`` is image pixel ``(x1 - 1, y1 - 1)``), placed at column 0 from canvas row
    ``top[k]`` on, crops in the order of ``idx``, at least ``gap`` black rows apart.

    One OpenCV call on the canvas then does the work of one call per crop: an erosion or
    dilation reaching fewer than ``gap`` rows, a distance transform (the nearest black
    pixel of a crop's pixel is never beyond its border) and a connected-component
    labelling give each crop what it would get alone. The crops start on even rows, so
    that labelling, which scans two rows at a time, numbers each crop's components in
    the same order as it would alone. Rasterised from the runs in one pass for all
    groups, never from the full image.

    Returns
    -------
    canvas : ndarray of uint8, shape (rows, max width + 2)
        The stacked crops (1 white, 0 black).
    top : ndarray of int
        Canvas row of each crop's first row.
    """
    height = table.height[idx] + 2
    step = height + gap
    step += step % 2
    top = step.cumsum() - step
    width = int(table.width[idx].max()) + 2
    canvas = np.zeros((int(top[-1] + height[-1]), width), np.uint8)
    slot = np.full(max(int(runs.group.max()), int(table.label[idx].max())) + 1, -1)
    slot[table.label[idx]] = np.arange(idx.size)
    crop = slot[runs.group]
    mine = crop >= 0
    crop = crop[mine]
    x1, x2 = runs.x1[mine], runs.x2[mine]
    # canvas position of each run's first pixel: its crop's top row, then the image
    # offset of the crop's pixel (0, 0)
    corner = (top - table.y1[idx] + 1) * width - table.x1[idx] + 1
    start = corner[crop] + runs.y[mine] * width + x1
    count = x2 - x1 + 1
    end = count.cumsum()
    canvas.ravel()[np.arange(end[-1]) + (start - end + count).repeat(count)] = 1
    return canvas, top


def group_crops(
    runs: Runs, table: GroupTable, idx: NDArray[np.int64]
) -> Iterator[tuple[int, int, int, NDArray[np.uint8]]]:
    """Yield ``(row, x0, y0, crop)`` for the groups at rows ``idx`` of ``table``.

    ``crop`` is the group's white pixels as a binary image with a one-pixel black border;
    its pixel ``(0, 0)`` is image pixel ``(x0, y0)``. Cut from one :func:`group_canvas`
    of all the groups asked for, so only they cost anything, and in one pass.
    """
    if len(idx) == 0:
        return
    canvas, top = group_canvas(runs, table, idx)
    x0 = (table.x1[idx] - 1).tolist()
    y0 = (table.y1[idx] - 1).tolist()
    bottom = (top + table.height[idx] + 2).tolist()
    right = (table.width[idx] + 2).tolist()
    for i, a, b, w, x, y in zip(idx.tolist(), top.tolist(), bottom, right, x0, y0, strict=True):
        yield i, x, y, canvas[a:b, :w].copy()
