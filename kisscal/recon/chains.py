"""Two-camera ghosts that move smoothly: runs of pairs made of two markers' blobs.

Two markers that move together (two pelvis markers, say), each seen by one
camera of a pair, can lie on each other's epipolar lines for many fields: their rays
cross at a point that moves as smoothly as a marker, so the pairs' continuity check
(:mod:`kisscal.recon.pairs`) takes it, for a run of fields, and the blobs go to the
ghost instead of the markers (issue 27: 3.6 % ghosts on one three-camera trial, all
made by the rays of the sacrum and a front pelvis marker). Off by default
(``two_camera_split_mm`` = 0): see that parameter for what it changes downstream.

Each blob is followed in its own image to the neighbouring field (the nearest blob of
the camera, when the next nearest is at least twice as far). The blobs of a real marker
continue together: from one point in one field to one point in the next. A ghost's
blobs, where its run starts or ends, come from (or go to) two different points, each of
them the marker the blob shows. So the two-camera points linked field to field through
both their blobs form runs, and a run whose points' blobs somewhere continue into two
different points is dropped: its blobs are freed for the markers they show.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from kisscal.recon.group import Solved, renumber, triangulate_markers
from kisscal.recon.params import ReconParams

#: Pixel offset per (field, camera) cell, so that one k-d tree keeps every image apart.
_CELL_PX = 1e6


def blob_neighbours(
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    n_cameras: int,
    step: int,
    gate_px: float,
) -> NDArray[np.int64]:
    """Per blob, the blob of its camera in field ``field + step`` that it continues: the
    nearest within ``gate_px``, when no other lies within twice that distance; -1 if none.

    Examples
    --------
    >>> f, c = np.array([0, 1, 1]), np.array([0, 0, 0])
    >>> uv = np.array([[10.0, 10.0], [11.0, 10.0], [40.0, 10.0]])
    >>> blob_neighbours(f, c, uv, 1, 1, 20.0)
    array([ 1, -1, -1])
    """
    cell = (field * n_cameras + camera).astype(float) * _CELL_PX
    tree = cKDTree(np.column_stack([uv, cell]))
    at = ((field + step) * n_cameras + camera).astype(float) * _CELL_PX
    d, j = tree.query(np.column_stack([uv, at]), k=2, distance_upper_bound=2.0 * gate_px)
    ok = (d[:, 0] <= gate_px) & ~(d[:, 1] < 2.0 * d[:, 0])
    return np.where(ok, j[:, 0], -1)


def _continuations(
    marker: NDArray[np.int64],
    rows: NDArray[np.int64],
    size: NDArray[np.int64],
    table: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]],
    n_cameras: int,
    gate_px: float,
) -> tuple[dict[int, NDArray[np.int64]], dict[int, NDArray[np.int64]]]:
    """Per step (-1, 1) and two-camera point (its blobs ``rows``, (m, 2)): the points its
    two blobs continue into (-1: none), and the two-camera point both continue into (its
    run's neighbour; -1: none)."""
    nxt, link = {}, {}
    for step in (-1, 1):
        near = blob_neighbours(*table, n_cameras, step, gate_px)[rows]
        nxt[step] = np.where(near >= 0, marker[np.maximum(near, 0)], -1)
        same = np.all(nxt[step] >= 0, axis=1) & (nxt[step][:, 0] == nxt[step][:, 1])
        same &= size[np.maximum(nxt[step][:, 0], 0)] == 2
        link[step] = np.where(same, nxt[step][:, 0], -1)
    return nxt, link


def drop_split_runs(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
    solved: Solved | None = None,
) -> NDArray[np.int64]:
    """``marker`` without the runs of two-camera points whose blobs continue into two
    different points (see module docstring), renumbered.

    A point's blobs count as continuing into two different points where both lie more
    than ``params.two_camera_split_mm`` from where the point's run goes next (constant
    velocity through the point and the run's point on the other side, or the point
    itself at a run's end); blobs are followed within ``params.two_camera_follow_px``.

    Parameters
    ----------
    marker : ndarray of int, shape (n,)
        Point of each blob (-1: unused).
    field, camera, uv : ndarray
        The 2D table (linearised px).
    dlts : ndarray, shape (n_cameras, 11)
    params : ReconParams
    solved : Solved, optional
        Markers of this table triangulated before (:class:`~kisscal.recon.group.Solved`).

    Returns
    -------
    ndarray of int, shape (n,)
    """
    used = np.flatnonzero(marker >= 0)
    if len(used) == 0:
        return marker
    xyz = triangulate_markers(marker, camera, uv, dlts, params.reweight_iterations, solved).xyz_mm
    n_pts = int(marker.max()) + 1
    size = np.bincount(marker[used], minlength=n_pts)
    rows = used[size[marker[used]] == 2]
    rows = rows[np.argsort(marker[rows], kind="stable")].reshape(-1, 2)  # one pair per row
    pair = marker[rows[:, 0]]
    table = field, camera, uv
    nxt, link = _continuations(marker, rows, size, table, len(dlts), params.two_camera_follow_px)
    split = np.zeros(n_pts, dtype=bool)
    for step in (-1, 1):
        two = np.all(nxt[step] >= 0, axis=1) & (nxt[step][:, 0] != nxt[step][:, 1])
        back = link[-step]
        ahead = np.where((back >= 0)[:, None], 2 * xyz[pair] - xyz[np.maximum(back, 0)], xyz[pair])
        far = np.linalg.norm(xyz[nxt[step][two]] - ahead[two][:, None], axis=2)
        two[two] = np.all(far > params.two_camera_split_mm, axis=1)
        split[pair[two]] = True
    s = np.concatenate([pair[link[k] >= 0] for k in (-1, 1)])
    d = np.concatenate([link[k][link[k] >= 0] for k in (-1, 1)])
    _, run = connected_components(
        coo_matrix((np.ones(len(s)), (s, d)), shape=(n_pts, n_pts)), directed=False
    )
    bad_run = np.zeros(run.max(initial=0) + 1, dtype=bool)
    bad_run[run[split]] = True
    bad = bad_run[run] & (size == 2)
    if not bad.any():
        return marker
    return renumber(np.where((marker >= 0) & bad[np.maximum(marker, 0)], -1, marker), field)
