"""Per-group measures the tests need: bounding rectangle (Fig. 4), white and total pixels
(equations 4, 5), the first and last row of each group (equation 6) and the binary
centroid (equation 2)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

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

    @property
    def width(self) -> NDArray[np.int64]:
        """Columns covered by the bounding rectangle (w of equation 4)."""
        return self.x2 - self.x1 + 1

    @property
    def height(self) -> NDArray[np.int64]:
        """Scan lines covered by the bounding rectangle (h of equation 4)."""
        return self.y2 - self.y1 + 1

    @property
    def fill(self) -> NDArray[np.float64]:
        """WhitePixels / TotalPixels (equations 5 over 4)."""
        return self.pixels / (self.width * self.height)

    @property
    def x_binary(self) -> NDArray[np.float64]:
        """Binary centroid x (equation 2)."""
        return self.sum_x / self.pixels

    @property
    def y_binary(self) -> NDArray[np.float64]:
        """Binary centroid y (equation 2)."""
        return self.sum_y / self.pixels


def measure_groups(runs: Runs) -> GroupTable:
    """Measure every group of ``runs`` with segment reductions over runs sorted by group.

    Runs arrive in scan order; a stable sort by group keeps each group's runs in line
    order, so its first and last runs lie in its top and bottom scan lines.
    """
    order = np.argsort(runs.group, kind="stable")
    g = runs.group[order]
    y = runs.y[order]
    x1 = runs.x1[order]
    x2 = runs.x2[order]
    if g.size == 0:
        e = np.zeros(0, dtype=np.int64)
        f = np.zeros(0, dtype=float)
        return GroupTable(e, e, e, e, e, e, e, f, f, e, e, e, e)
    new_group = _changes(g)
    starts = np.flatnonzero(new_group)
    ends = _segment_ends(starts, g.size)
    length = x2 - x1 + 1
    pixels = np.add.reduceat(length, starts)
    # The mean column of a run is its mid-point (equation 3), so a run contributes
    # length * mid-point to the column sum.
    sum_x = np.add.reduceat(length * (x1 + x2) * 0.5, starts)
    sum_y = np.add.reduceat((length * y).astype(float), starts)
    new_line = new_group | _changes(y)
    line_id = np.cumsum(new_line) - 1
    line_starts = np.flatnonzero(new_line)
    rows = np.add.reduceat(new_line.astype(np.int64), starts)
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


def group_crops(
    runs: Runs, table: GroupTable, idx: NDArray[np.int64]
) -> Iterator[tuple[int, int, int, NDArray[np.uint8]]]:
    """Yield ``(row, x0, y0, crop)`` for the groups at rows ``idx`` of ``table``.

    ``crop`` is the group's white pixels as a binary image with a one-pixel black border;
    its pixel ``(0, 0)`` is image pixel ``(x0, y0)``. Rasterised from the run-length scan,
    never from the full image, so only the few groups asked for cost anything.
    """
    order = np.argsort(runs.group, kind="stable")
    sorted_groups = runs.group[order]
    lo = np.searchsorted(sorted_groups, table.label[idx])
    hi = np.searchsorted(sorted_groups, table.label[idx], side="right")
    for i, a, b in zip(idx, lo, hi, strict=True):
        mine = order[a:b]
        x0, y0 = int(table.x1[i]) - 1, int(table.y1[i]) - 1
        crop = np.zeros((table.height[i] + 2, table.width[i] + 2), np.uint8)
        count = runs.x2[mine] - runs.x1[mine] + 1
        row = np.repeat(runs.y[mine] - y0, count)
        col = np.repeat(runs.x1[mine] - x0, count) + (
            np.arange(row.size) - np.repeat(np.cumsum(count) - count, count)
        )
        crop[row, col] = 1
        yield int(i), x0, y0, crop
