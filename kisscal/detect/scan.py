"""Run-length scan and grouping by closeness of run mid-points (Shafiq et al. 2001, 2.1).

A *run* is a maximal horizontal stretch of white pixels in one scan line: its boundary pixels
P_i, P_i+1 are ``x1`` and ``x2`` and its mid-point is equation (3). Marker images are mostly
black, so only scan lines holding a white pixel are expanded into runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Runs:
    """Runs of white pixels in scan order (row, then column), with their group label.

    ``y``, ``x1``, ``x2`` are pixel indices (``x2`` inclusive); ``group`` is a label per run,
    the same for all runs of a group.
    """

    y: NDArray[np.int64]
    x1: NDArray[np.int64]
    x2: NDArray[np.int64]
    group: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.y.shape[0])

    @property
    def length(self) -> NDArray[np.int64]:
        """White pixels of each run, x2 - x1 + 1 (the summand of equation 5)."""
        return self.x2 - self.x1 + 1

    def take(self, index: NDArray[np.int64] | NDArray[np.bool_]) -> Runs:
        return Runs(self.y[index], self.x1[index], self.x2[index], self.group[index])


def scan_runs(white: NDArray[np.bool_]) -> tuple[NDArray[np.int64], ...]:
    """Return ``(y, x1, x2)`` of every run of ``True`` pixels in a 2-D boolean image.

    Scan lines without a white pixel are skipped before any per-column work, which is what
    makes the scan cheap on marker images (equation 3's boundary pixels come out directly).
    """
    rows = white.any(axis=1).nonzero()[0]
    if rows.size == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty
    width = white.shape[1]
    index = np.flatnonzero(white[rows])
    line, x = np.divmod(index, width)
    # Adding the line number makes pixels of different lines never consecutive, so a run
    # is a maximal stretch of consecutive keys.
    key = index + line
    start = np.ones(key.size, dtype=bool)
    np.not_equal(key[1:], key[:-1] + 1, out=start[1:])
    first = start.nonzero()[0]
    last = np.empty_like(first)
    last[:-1] = first[1:] - 1
    last[-1] = key.size - 1
    # (already int64 where intp is; no copies then)
    y = rows[line[first]].astype(np.int64, copy=False)
    return y, x[first].astype(np.int64, copy=False), x[last].astype(np.int64, copy=False)


def _neighbour_pairs(
    y: NDArray[np.int64],
    x1: NDArray[np.int64],
    x2: NDArray[np.int64],
    width: int,
    closeness_x_px: float,
    closeness_rows: int,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pairs (a, b) of runs with b in one of the ``closeness_rows`` lines above a, close in x.

    Runs are sorted by (y, x) and disjoint within a line, so for a given run the close runs
    of an earlier line form one contiguous index range, found by binary search on a key
    that orders all runs by line then column.
    """
    gap = int(np.floor(closeness_x_px)) + 1
    stride = width + 2 * gap + 8
    key_start = y * stride + x1
    key_end = y * stride + x2
    firsts, seconds = [], []
    for d in range(1, closeness_rows + 1):
        base = (y - d) * stride
        lo = key_end.searchsorted(base + x1 - gap, side="left")
        hi = key_start.searchsorted(base + x2 + gap, side="right")
        count = np.maximum(hi - lo, 0)
        most = int(count.max(initial=0))
        if most == 0:
            continue
        if most == 1:  # the usual case: no run touches two runs of that line
            a = count.nonzero()[0]
            firsts.append(a)
            seconds.append(lo[a])
            continue
        a = np.arange(y.size).repeat(count)
        offset = np.arange(a.size) - (count.cumsum() - count).repeat(count)
        firsts.append(a)
        seconds.append(lo.repeat(count) + offset)
    if len(firsts) == 1:
        return firsts[0], seconds[0]
    if not firsts:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    return np.concatenate(firsts), np.concatenate(seconds)


def _components(n: int, a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.int64]:
    """Label connected components of the graph on ``n`` nodes with edges (a, b).

    Hook-and-jump union: every edge whose ends have different roots hooks the larger root
    under the smaller, then pointers are jumped to their roots; labels only decrease so no
    cycle can form. The result labels each node with the smallest node index of its
    component, i.e. the first run of the group in scan order.
    """
    label = np.arange(n)
    while a.size:
        la, lb = label[a], label[b]
        differ = la != lb
        if not differ.any():
            break
        la, lb = la[differ], lb[differ]
        a, b = a[differ], b[differ]
        label[np.maximum(la, lb)] = np.minimum(la, lb)
        while True:
            jumped = label[label]
            if (jumped == label).all():  # array_equal's checks cost more than the compare
                break
            label = jumped
    return label


def group_runs(
    white: NDArray[np.bool_], closeness_x_px: float = 0.0, closeness_rows: int = 1
) -> Runs:
    """Scan ``white`` and group its runs by closeness of mid-points (Shafiq et al. 2001, 2.1).

    Parameters
    ----------
    white : ndarray of bool, shape (h, w)
        Thresholded image.
    closeness_x_px : float
        Extra horizontal gap (pixels) bridged between runs of neighbouring lines; two runs
        are close when ``|x_m - x_m'| <= (len + len') / 2 + closeness_x_px`` (equation 3's
        mid-points), which for 0 means the runs touch (8-connected).
    closeness_rows : int
        Largest line distance at which runs are compared.

    Returns
    -------
    Runs
        All runs in scan order, ``group`` numbered 0, 1, ... in order of each group's first
        run, as the paper numbers groups while scanning.
    """
    y, x1, x2 = scan_runs(white)
    a, b = _neighbour_pairs(y, x1, x2, white.shape[1], closeness_x_px, closeness_rows)
    label = _components(y.size, a, b)
    # Roots are the first run of their group, so numbering roots in index order numbers
    # groups in scan order (no sort needed).
    is_root = label == np.arange(label.size)
    group = is_root.cumsum()[label] - 1
    return Runs(y, x1, x2, group)
