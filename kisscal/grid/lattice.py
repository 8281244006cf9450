"""Lattice indexing: give every detected grid dot its (row, col) in the rows x cols grid.

Shafiq et al. 2001, section 3.2 needs "the co-ordinates of grid points to be detected by
each camera" and the row/column each belongs to, since the deviations of the rows and
columns from straight lines drive the linearisation. The method here is kisscal's own:

1. the two lattice vectors are the medians of the nearest-neighbour difference vectors
   (robust to a few extra blobs and to the slow change of spacing under lens distortion);
2. the lattice grows breadth-first from a dot near the middle that has all four
   neighbours, predicting each next dot by linear extrapolation from the two previous
   ones along the row or column, so barrel/pincushion bending is followed step by step;
3. a rows x cols window with the most dots is kept (blobs on lattice positions beyond
   the grid are rejected);
4. a smooth 4th-order fit of position over (row, col) rejects mis-indexed blobs and
   predicts the positions of missing dots.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from kisscal._shared import as_points
from kisscal.errors import EstimationFailed, InputError
from kisscal.grid.params import GridParams
from kisscal.grid.poly import poly_terms


@dataclass(frozen=True, eq=False)
class LatticeIndex:
    """Row and column of every detected dot.

    Attributes
    ----------
    rows, cols : int
        Grid size.
    row, col : ndarray of int, shape (N,)
        Lattice position of each input dot; -1 for a dot that was rejected. Row 0 is the
        top row in the image, column 0 the left column.
    missing_rc : ndarray of int, shape (M, 2)
        ``(row, col)`` of grid positions without a dot.
    missing_uv : ndarray, shape (M, 2)
        Where the missing dots would be (px), from a smooth fit over the found dots.
    rejected : ndarray of int
        Indices (into the input) of blobs that are not grid dots.
    """

    rows: int
    cols: int
    row: NDArray[np.int64]
    col: NDArray[np.int64]
    missing_rc: NDArray[np.int64]
    missing_uv: NDArray[np.float64]
    rejected: NDArray[np.int64]

    @property
    def indexed(self) -> NDArray[np.bool_]:
        """Mask of the input dots that have a lattice position."""
        return self.row >= 0

    @property
    def n_indexed(self) -> int:
        """Number of indexed dots."""
        return int(np.count_nonzero(self.indexed))


def _principal_direction(vecs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit axis (sign-free) of 2D vectors: mean of doubled angles, so v and -v agree."""
    ang = np.arctan2(vecs[:, 1], vecs[:, 0])
    mean2 = np.arctan2(np.median(np.sin(2 * ang)), np.median(np.cos(2 * ang)))
    return np.array([np.cos(mean2 / 2), np.sin(mean2 / 2)])


def _median_vector(vecs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Median of vectors after folding each onto the half-plane of their common axis."""
    axis = _principal_direction(vecs)
    # A second pass around the first estimate discards vectors far from the axis.
    signs = np.where(vecs @ axis < 0, -1.0, 1.0)
    folded = vecs * signs[:, None]
    return np.median(folded, axis=0)


def _common_direction(steps: NDArray[np.float64]) -> NDArray[np.float64]:
    """The steps along the lattice direction most of them follow.

    With square pixels a square grid's rows and columns are equally far apart, so the
    nearest neighbour of one dot is beside it and of the next below it (spacing changes
    across the image with perspective and distortion). The two lattice directions are
    found together, modulo 90 degrees (median of quadrupled angles); the larger group of
    steps is kept. Without such a mix (non-square pixels) every step is kept.
    """
    ang = np.arctan2(steps[:, 1], steps[:, 0])
    axis = np.arctan2(np.median(np.sin(4 * ang)), np.median(np.cos(4 * ang))) / 4
    along = np.abs(np.cos(ang - axis)) >= np.abs(np.sin(ang - axis))
    return steps[along] if 2 * np.count_nonzero(along) >= len(steps) else steps[~along]


def lattice_vectors(dots_uv: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Typical column step and row step of a dot lattice, in px.

    Parameters
    ----------
    dots_uv : array_like, shape (N, 2)
        Dot centroids, px.

    Returns
    -------
    e_col, e_row : ndarray, shape (2,)
        Step from a dot to its right neighbour (``u`` component > 0) and to the neighbour
        below it (``v`` component > 0).
    """
    pts = np.asarray(dots_uv, dtype=float)
    k = min(9, len(pts))
    tree = cKDTree(pts)
    _, nb = tree.query(pts, k=k)
    diff = pts[nb[:, 1:]] - pts[:, None, :]  # (N, k-1, 2), sorted by distance
    first = _median_vector(_common_direction(diff[:, 0, :]))
    unit = first / np.linalg.norm(first)
    # Second vector: the shortest neighbour step of each dot more than 30 deg off the first.
    dist = np.linalg.norm(diff, axis=2)
    sin_off = np.abs(diff[..., 0] * unit[1] - diff[..., 1] * unit[0]) / np.maximum(dist, 1e-12)
    off = sin_off > 0.5
    has = off.any(axis=1)
    if np.count_nonzero(has) < 3:
        raise EstimationFailed("grid dots do not form a two-dimensional lattice")
    j = np.argmax(off, axis=1)
    second = _median_vector(diff[np.flatnonzero(has), j[has], :])
    a, b = first, second
    # The column step is the more horizontal one (a grid rotated well under 45 deg).
    if abs(a[0]) / np.linalg.norm(a) < abs(b[0]) / np.linalg.norm(b):
        a, b = b, a
    e_col = a if a[0] > 0 else -a
    e_row = b if b[1] > 0 else -b
    return e_col, e_row


def lattice_pixel_aspect(dots_uv: ArrayLike, cell_aspect: float = 1.0) -> float:
    """The pixel aspect (``fy / fx`` inverted: width / height of a round dot's image) of
    the camera that imaged a dot lattice, from the lattice's two steps.

    A lattice of square cells (``cell_aspect`` = row pitch / column pitch, 1 for square)
    seen face-on by a camera whose pixels are ``a`` times taller than wide has column and
    row steps ``(a s cos f, s sin f)`` and ``rho (-a s sin f, s cos f)`` for some scale
    ``s`` and in-plane rotation ``f``. Their cross product is ``a s^2 rho`` and their
    squared lengths add up (the row step divided by ``rho``) to ``s^2 (a^2 + 1)``, so
    ``a`` solves ``a^2 - K a + 1 = 0`` with ``K`` the ratio of the two; of its two roots
    ``a`` and ``1 / a``, the one that makes the unstretched steps orthogonal and of the
    right length ratio is kept. The steps are taken from the third of the dots nearest the
    grid's middle, where lens distortion changes least. A grid tilted by ``t`` from
    face-on reads ``a`` off by at most ``1 - cos t`` (0.1 % at 3 degrees).

    Examples
    --------
    >>> import numpy as np
    >>> r, c = np.mgrid[0:15, 0:20]
    >>> angle = np.radians(4.0)
    >>> X = 30 * (c * np.cos(angle) - r * np.sin(angle))
    >>> Y = 30 * (c * np.sin(angle) + r * np.cos(angle))
    >>> dots = np.column_stack([1.94 * X.ravel() + 100, Y.ravel() + 40])
    >>> round(lattice_pixel_aspect(dots), 4)
    1.94
    """
    dots = as_points(dots_uv, 2, "dots_uv")
    if len(dots) < 9:
        raise EstimationFailed(f"grid: {len(dots)} dots are too few for the lattice's pixel aspect")
    # lens distortion bends the outer rows and columns most: the steps near the middle of
    # the grid, where it changes least, carry the camera's aspect
    centre = np.median(dots, axis=0)
    near = np.argsort(np.linalg.norm(dots - centre, axis=1))[: max(len(dots) // 3, 30)]
    e_col, e_row = lattice_vectors(dots[near])
    rho = float(cell_aspect)
    det = abs(e_col[0] * e_row[1] - e_col[1] * e_row[0]) / rho
    k = (e_col @ e_col + (e_row @ e_row) / rho**2) / det
    root = np.sqrt(max(k * k - 4.0, 0.0))
    best, score = 1.0, np.inf
    for a in ((k + root) / 2, (k - root) / 2):
        u1 = e_col / np.array([a, 1.0])
        u2 = e_row / np.array([a, 1.0]) / rho
        n1, n2 = np.linalg.norm(u1), np.linalg.norm(u2)
        mismatch = abs(u1 @ u2) / (n1 * n2) + abs(n1 / n2 - 1.0)
        if mismatch < score:
            best, score = float(a), mismatch
    return best


_STEPS = ((0, 1), (0, -1), (1, 0), (-1, 0))


def _predict(
    key: tuple[int, int],
    at: dict[tuple[int, int], int],
    pts: NDArray[np.float64],
    e_col: NDArray[np.float64],
    e_row: NDArray[np.float64],
) -> NDArray[np.float64] | None:
    """Predicted position of lattice position ``key`` from the dots indexed around it.

    Every local rule that applies votes: linear extrapolation along a row or column
    (``2 p[k-d] - p[k-2d]``) and the parallelogram of two neighbours and their common
    diagonal neighbour (``p[k-d1] + p[k-d2] - p[k-d1-d2]``); both follow the slow bending
    of the lattice under lens distortion. The median of the votes keeps one wrongly
    accepted blob from steering the growth. With a single indexed neighbour, the global
    lattice vector is used.
    """
    r, c = key
    votes = []
    for dr, dc in _STEPS:
        a, b = (r - dr, c - dc), (r - 2 * dr, c - 2 * dc)
        if a in at and b in at:
            votes.append(2 * pts[at[a]] - pts[at[b]])
    for dr in (1, -1):
        for dc in (1, -1):
            a, b, d = (r - dr, c), (r, c - dc), (r - dr, c - dc)
            if a in at and b in at and d in at:
                votes.append(pts[at[a]] + pts[at[b]] - pts[at[d]])
    if votes:
        return np.median(np.array(votes), axis=0)
    for dr, dc in _STEPS:
        a = (r - dr, c - dc)
        if a in at:
            return pts[at[a]] + dr * e_row + dc * e_col
    return None


def _grow(
    pts: NDArray[np.float64],
    tree: cKDTree,
    seed: int,
    e_col: NDArray[np.float64],
    e_row: NDArray[np.float64],
    tol_px: float,
) -> dict[tuple[int, int], int]:
    """Breadth-first growth of the lattice from a seed dot; returns {(row, col): dot}."""
    at: dict[tuple[int, int], int] = {(0, 0): seed}
    taken = np.zeros(len(pts), dtype=bool)
    taken[seed] = True
    queue = deque([(0, 0)])
    while queue:
        r, c = queue.popleft()
        for dr, dc in _STEPS:
            key = (r + dr, c + dc)
            if key in at:
                continue
            pred = _predict(key, at, pts, e_col, e_row)
            dist, j = tree.query(pred)
            if dist <= tol_px and not taken[j]:
                at[key] = int(j)
                taken[j] = True
                queue.append(key)
    return at


def _best_window(keys: NDArray[np.int64], rows: int, cols: int) -> tuple[int, int]:
    """Top-left (row, col) of the rows x cols window holding the most lattice positions."""
    r0, c0 = keys.min(axis=0)
    occ = np.zeros((keys[:, 0].max() - r0 + 1, keys[:, 1].max() - c0 + 1), dtype=int)
    occ[keys[:, 0] - r0, keys[:, 1] - c0] = 1
    h, w = occ.shape
    wr, wc = min(rows, h), min(cols, w)
    csum = np.zeros((h + 1, w + 1), dtype=int)
    csum[1:, 1:] = occ.cumsum(0).cumsum(1)
    counts = csum[wr:, wc:] - csum[:-wr, wc:] - csum[wr:, :-wc] + csum[:-wr, :-wc]
    i, j = np.unravel_index(np.argmax(counts), counts.shape)
    return int(i + r0), int(j + c0)


def _smooth_fit(
    rc: NDArray[np.float64], uv: NDArray[np.float64], rows: int, cols: int
) -> NDArray[np.float64]:
    """Coefficients (15, 2) of a 4th-order fit of position over normalised (col, row)."""
    z = poly_terms(rc[:, 1] / (cols - 1) * 2 - 1, rc[:, 0] / (rows - 1) * 2 - 1)
    coef, *_ = np.linalg.lstsq(z, uv, rcond=None)
    return coef


def _smooth_eval(coef: NDArray[np.float64], rc: NDArray[np.float64], rows: int, cols: int):
    z = poly_terms(rc[:, 1] / (cols - 1) * 2 - 1, rc[:, 0] / (rows - 1) * 2 - 1)
    return z @ coef


def index_lattice(dots_uv: ArrayLike, params: GridParams | None = None) -> LatticeIndex:
    """Assign every detected dot its (row, col) in the linearisation grid.

    Parameters
    ----------
    dots_uv : array_like, shape (N, 2)
        Detected blob centroids in px (grid dots plus possibly extra blobs).
    params : GridParams, optional
        Grid size, matching tolerance, outlier limits and the least fraction to index.

    Returns
    -------
    LatticeIndex
        Row/column per dot, rejected blobs, and the missing positions with predicted px.

    Raises
    ------
    KisscalError
        When fewer than ``params.min_indexed_fraction`` of ``rows * cols`` dots can be
        indexed, or the input is not an (N, 2) array of finite numbers.
    """
    p = params or GridParams()
    pts = np.asarray(dots_uv, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise InputError(f"grid dots must be an (N, 2) array of u, v pixels, got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise InputError("grid dots contain NaN or infinite coordinates")
    n_grid = p.rows * p.cols
    need = int(np.ceil(p.min_indexed_fraction * n_grid))
    if len(pts) < need:
        raise EstimationFailed(
            f"found {len(pts)} blobs but a {p.rows} x {p.cols} grid needs at least {need} "
            f"dots ({p.min_indexed_fraction:.0%}): check that the grid fills the view"
        )
    e_col, e_row = lattice_vectors(pts)
    tree = cKDTree(pts)

    # Seed: near the middle, with all four neighbours where the lattice vectors say.
    centre = np.median(pts, axis=0)
    order = np.argsort(np.linalg.norm(pts - centre, axis=1))
    tol = p.match_tol * min(np.linalg.norm(e_col), np.linalg.norm(e_row))
    seed = int(order[0])
    for i in order[:50]:
        nbrs = pts[i] + np.array([e_col, -e_col, e_row, -e_row])
        d, _ = tree.query(nbrs)
        if np.all(d <= tol):
            seed = int(i)
            break
    at = _grow(pts, tree, seed, e_col, e_row, tol)

    keys = np.array(list(at.keys()), dtype=np.int64)
    idx = np.array(list(at.values()), dtype=np.int64)
    r0, c0 = _best_window(keys, p.rows, p.cols)
    inside = (
        (keys[:, 0] >= r0)
        & (keys[:, 0] < r0 + p.rows)
        & (keys[:, 1] >= c0)
        & (keys[:, 1] < c0 + p.cols)
    )
    keys = keys[inside] - np.array([r0, c0])
    idx = idx[inside]

    # Reject mis-indexed blobs against a smooth map (row, col) -> (u, v).
    good = np.ones(len(idx), dtype=bool)
    for _ in range(3):
        if np.count_nonzero(good) < 15:
            break
        coef = _smooth_fit(keys[good].astype(float), pts[idx[good]], p.rows, p.cols)
        res = np.linalg.norm(
            _smooth_eval(coef, keys.astype(float), p.rows, p.cols) - pts[idx], axis=1
        )
        sigma = 1.4826 * np.median(res[good])
        limit = max(p.outlier_px, p.outlier_sigmas * sigma)
        new_good = res <= limit
        if np.array_equal(new_good, good):
            break
        good = new_good
    keys, idx = keys[good], idx[good]

    row = np.full(len(pts), -1, dtype=np.int64)
    col = np.full(len(pts), -1, dtype=np.int64)
    row[idx] = keys[:, 0]
    col[idx] = keys[:, 1]
    if len(idx) < need:
        raise EstimationFailed(
            f"only {len(idx)} of {n_grid} grid dots ({len(idx) / n_grid:.0%}) could be indexed "
            f"as a {p.rows} x {p.cols} lattice; need {p.min_indexed_fraction:.0%}: check the "
            "grid size, that the grid fills the view, and the dot detection"
        )
    occupied = np.zeros((p.rows, p.cols), dtype=bool)
    occupied[keys[:, 0], keys[:, 1]] = True
    missing_rc = np.argwhere(~occupied).astype(np.int64)
    coef = _smooth_fit(keys.astype(float), pts[idx], p.rows, p.cols)
    missing_uv = _smooth_eval(coef, missing_rc.astype(float), p.rows, p.cols).reshape(-1, 2)
    rejected = np.flatnonzero(row < 0).astype(np.int64)
    return LatticeIndex(p.rows, p.cols, row, col, missing_rc, missing_uv, rejected)
