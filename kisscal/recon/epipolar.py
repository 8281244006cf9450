"""Epipolar geometry of DLT cameras and epipolar distances of candidate point pairs.

The thesis (Küçük 2005, 3.3.4) stores each epipolar line as gain and offset ``v = m u + n``
and tests horizontal/vertical offsets against a band (eqs. 3.1-3.8); Shafiq et al. (2001,
eq. 8) write the same line bilinearly in the source point. Both are the fundamental matrix
``F`` of the two DLT cameras: the line of point ``x_i`` in camera ``j`` is ``F x_i``. We use
the homogeneous line and the perpendicular point-to-line distance, which is what the
thesis' band test approximates and which stays defined for vertical lines.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import lexsort_ints
from kisscal.dlt.model import camera_centre_mm, fundamental_from_dlt

__all__ = [
    "all_fundamentals",
    "camera_centre_mm",
    "candidate_pairs",
    "distance_matrix_px",
    "epipolar_lines",
    "field_pairs",
    "fundamental_from_dlt",
    "pair_distances_px",
]

_CHUNK = 1 << 15  # (field, blob, blob) cells of one camera pair tested at once: in the CPU cache


def epipolar_lines(F: ArrayLike, uv_i: ArrayLike) -> NDArray[np.float64]:
    """Epipolar lines ``(a, b, c)`` with ``a u + b v + c = 0`` in the target camera.

    Lines are normalised so that ``a^2 + b^2 = 1``: ``line . (u, v, 1)`` is then the signed
    perpendicular distance in pixels.

    Parameters
    ----------
    F : array_like, shape (3, 3)
        Fundamental matrix from :func:`fundamental_from_dlt` (source i -> target j).
    uv_i : array_like, shape (..., 2)
        Points in the source camera (linearised px).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    F = np.asarray(F, dtype=float)
    uv = np.asarray(uv_i, dtype=float)
    lines = uv @ F[:, :2].T + F[:, 2]
    return lines / np.hypot(lines[..., 0], lines[..., 1])[..., None]


def pair_distances_px(
    F: ArrayLike, uv_i: ArrayLike, uv_j: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Perpendicular epipolar distances of paired points, in both directions.

    Parameters
    ----------
    F : array_like, shape (3, 3)
        Fundamental matrix of cameras i -> j.
    uv_i, uv_j : array_like, shape (n, 2)
        Row k of each is one candidate pair (point in camera i, point in camera j).

    Returns
    -------
    d_in_j, d_in_i : ndarray, shape (n,)
        Distance (px) of ``uv_j`` from the line of ``uv_i`` in camera j, and of ``uv_i``
        from the line of ``uv_j`` in camera i (thesis eq. 3.9 asks both to be small).
    """
    F = np.asarray(F, dtype=float)
    uv_i = np.asarray(uv_i, dtype=float)
    uv_j = np.asarray(uv_j, dtype=float)
    line_j = epipolar_lines(F, uv_i)
    line_i = epipolar_lines(F.T, uv_j)
    d_j = np.abs(line_j[:, 0] * uv_j[:, 0] + line_j[:, 1] * uv_j[:, 1] + line_j[:, 2])
    d_i = np.abs(line_i[:, 0] * uv_i[:, 0] + line_i[:, 1] * uv_i[:, 1] + line_i[:, 2])
    return d_j, d_i


def distance_matrix_px(F: ArrayLike, uv_i: ArrayLike, uv_j: ArrayLike) -> NDArray[np.float64]:
    """Symmetric epipolar distance of every point of camera i to every point of camera j.

    Returns
    -------
    ndarray, shape (n_i, n_j)
        ``max`` of the two perpendicular distances (px) of each pair.
    """
    F = np.asarray(F, dtype=float)
    line_j = epipolar_lines(F, uv_i)  # (n_i, 3)
    line_i = epipolar_lines(F.T, uv_j)  # (n_j, 3)
    uv_i1 = np.column_stack([np.asarray(uv_i, float), np.ones(len(line_j))])
    uv_j1 = np.column_stack([np.asarray(uv_j, float), np.ones(len(line_i))])
    return np.maximum(np.abs(line_j @ uv_j1.T), np.abs(uv_i1 @ line_i.T))


def all_fundamentals(dlts: ArrayLike) -> NDArray[np.float64]:
    """Fundamental matrices of every ordered camera pair.

    Parameters
    ----------
    dlts : array_like, shape (n_cameras, 11)

    Returns
    -------
    ndarray, shape (n_cameras, n_cameras, 3, 3)
        ``F[i, j]`` maps points of camera i to lines in camera j; the diagonal is zero.
    """
    dlts = np.asarray(dlts, dtype=float)
    n = len(dlts)
    F = np.zeros((n, n, 3, 3))
    for i in range(n):
        for j in range(i + 1, n):
            F[i, j] = fundamental_from_dlt(dlts[i], dlts[j])
            F[j, i] = F[i, j].T
    return F


def field_pairs(
    field_i: NDArray[np.int64], field_j: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """All index pairs (a, b) with ``field_i[a] == field_j[b]``, without a loop over fields.

    Parameters
    ----------
    field_i, field_j : ndarray of int, sorted ascending
        Field of each point of camera i and of camera j.

    Returns
    -------
    a, b : ndarray of int
        Indices into ``field_i`` and ``field_j``.
    """
    start = np.searchsorted(field_j, field_i, side="left")
    stop = np.searchsorted(field_j, field_i, side="right")
    counts = stop - start
    a = np.repeat(np.arange(len(field_i)), counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    b = np.repeat(start, counts) + (np.arange(len(a)) - first)
    return a, b


def candidate_pairs(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    F: NDArray[np.float64],
    band_px: float,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Epipolar-consistent blob pairs of a whole trial, for every camera pair at once.

    Every blob of camera i is paired with every blob of camera j (i < j) in the same field;
    a pair is kept when each point lies within ``band_px`` of the other's epipolar line
    (thesis 3.3.4-3.3.5, "lying on an epipolar line" in both directions).

    Parameters
    ----------
    field, camera : array_like of int, shape (n,)
        Field and camera index (0-based, into ``F``) of each blob.
    uv : array_like, shape (n, 2)
        Linearised pixel coordinates.
    F : ndarray, shape (n_cameras, n_cameras, 3, 3)
        From :func:`all_fundamentals`.
    band_px : float
        Epipolar band half-width (px).

    Returns
    -------
    a, b : ndarray of int
        Row indices of the pair's blobs, with ``camera[a] < camera[b]``; ordered by camera
        pair, then by ``a`` and ``b`` in (field, row) order.
    distance_px : ndarray
        Larger of the two perpendicular distances of the pair.
    """
    field = np.asarray(field, dtype=np.int64)
    camera = np.asarray(camera, dtype=np.int64)
    uv = np.asarray(uv, dtype=float)
    n_cam = F.shape[0]
    cells = _Cells(field, camera, uv, n_cam)
    out_a, out_b, out_d = [], [], []
    for i, j in itertools.combinations(range(n_cam), 2):
        rows_i, rows_j = cells.rows[i], cells.rows[j]
        if len(rows_i) == 0 or len(rows_j) == 0:
            continue
        # one line per blob, not per pair (and of all the camera's blobs at once: the
        # matrix product rounds differently for other numbers of rows)
        lines_j = epipolar_lines(F[i, j], uv[rows_i])
        lines_i = epipolar_lines(F[j, i], uv[rows_j])
        for wi, wj in zip(cells.windows[i], cells.windows[j], strict=True):
            if wi.n_slots == 0 or wj.n_slots == 0:
                continue
            # every (field, blob of i, blob of j) cell of the window at once; the padding
            # is NaN, which no band holds
            line = np.full((3, len(wi.u), wi.n_slots), np.nan)
            line[:, wi.cell[0], wi.cell[1]] = lines_j[wi.first : wi.first + len(wi.cell[0])].T
            # one direction first: it rejects most pairs, the other is computed for the rest.
            # In place and on contiguous tables (the cells are 2x the pairs: every
            # temporary counts), in the order of a u + b v + c
            d = line[0][:, :, None] * wj.u[:, None, :]
            d += line[1][:, :, None] * wj.v[:, None, :]
            d += line[2][:, :, None]
            np.abs(d, out=d)
            f, p, q = np.nonzero(d < band_px)
            ia, jb, d = wi.pos[f, p], wj.pos[f, q], d[f, p, q]
            a, b = rows_i[ia], rows_j[jb]
            li, uva = lines_i[jb], uv[a]
            d = np.maximum(d, np.abs(li[:, 0] * uva[:, 0] + li[:, 1] * uva[:, 1] + li[:, 2]))
            keep = d < band_px
            out_a.append(a[keep])
            out_b.append(b[keep])
            out_d.append(d[keep])
    if not out_a:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, np.zeros(0)
    return np.concatenate(out_a), np.concatenate(out_b), np.concatenate(out_d)


@dataclass(frozen=True)
class _Window:
    """One camera's blobs in a window of fields, as dense (field, slot) tables.

    Attributes
    ----------
    cell : tuple of ndarray
        (field within the window, slot) of each blob, in the camera's row order.
    first : int
        Position of the window's first blob among the camera's rows.
    n_slots : int
        Slots of the window's fullest cell (0: no blob).
    u, v : ndarray, shape (n_fields, n_slots)
        Pixel coordinates of each cell's blobs, NaN where a cell has fewer.
    pos : ndarray of int, shape (n_fields, n_slots)
        Position of each blob among the camera's rows (0 in the padding).
    """

    cell: tuple[NDArray[np.int64], NDArray[np.int64]]
    first: int
    n_slots: int
    u: NDArray[np.float64]
    v: NDArray[np.float64]
    pos: NDArray[np.int64]


class _Cells:
    """A trial's blobs as (camera, field) cells, for dense pair tests over windows of fields.

    Blob k of a cell gets slot k (row order); a window holds as many consecutive fields as
    keep ``fields x slots x slots`` within ``_CHUNK`` for the fullest cell of the trial:
    the temporary arrays of a camera pair stay in the CPU cache (twice as fast as one
    window) and bounded on long or crowded trials.
    """

    def __init__(
        self,
        field: NDArray[np.int64],
        camera: NDArray[np.int64],
        uv: NDArray[np.float64],
        n_cam: int,
    ) -> None:
        order = lexsort_ints((field, camera))  # rows grouped by camera, fields ascending
        lo = int(field.min()) if len(field) else 0
        f_idx = field - lo
        if len(field) and int(f_idx.max()) >= len(field):  # sparse field numbers
            f_idx = np.unique(field, return_inverse=True)[1].reshape(-1)
        n_fields = int(f_idx.max()) + 1 if len(f_idx) else 0
        cell = camera[order] * (n_fields + 1) + f_idx[order]
        k = np.arange(len(cell))
        slot = k - np.maximum.accumulate(np.where(np.r_[True, cell[1:] != cell[:-1]], k, 0))
        per_window = max(1, _CHUNK // (int(slot.max(initial=0)) + 1) ** 2)
        edges = np.r_[np.arange(0, n_fields, per_window), n_fields]
        bounds = np.searchsorted(camera[order], np.arange(n_cam + 1))
        self.rows: list[NDArray[np.int64]] = []
        self.windows: list[list[_Window]] = []
        for c in range(n_cam):
            rows = order[bounds[c] : bounds[c + 1]]
            fc, sc = f_idx[rows], slot[bounds[c] : bounds[c + 1]]
            cuts = np.searchsorted(fc, edges)
            self.rows.append(rows)
            self.windows.append(
                [
                    _window(fc[a:b] - f0, sc[a:b], uv[rows[a:b]], int(a), int(f1 - f0))
                    for a, b, f0, f1 in zip(cuts[:-1], cuts[1:], edges[:-1], edges[1:], strict=True)
                ]
            )


def _window(
    f: NDArray[np.int64], s: NDArray[np.int64], uv: NDArray[np.float64], first: int, n_f: int
) -> _Window:
    """The :class:`_Window` of blobs in fields ``f`` (of ``n_f``) and slots ``s``, the
    first of which is at position ``first`` among their camera's rows."""
    n_slots = int(s.max()) + 1 if len(s) else 0
    table = np.full((2, n_f, n_slots), np.nan)
    table[:, f, s] = uv.T
    pos = np.zeros((n_f, n_slots), dtype=np.int64)
    pos[f, s] = np.arange(first, first + len(f))
    return _Window((f, s), first, n_slots, table[0], table[1], pos)
