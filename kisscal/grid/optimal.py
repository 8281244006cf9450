"""Primary grid and optimal grid (Küçük 2005, section 2.2, eq. 2.1).

Non-square pixels. The thesis' optimal grid is a scaled, rotated and translated copy of
the primary grid. A rotation in pixel coordinates is only a rotation of the grid when the
pixels are square; on a 752 x 291 video field they are about twice as tall as wide
(fy ~ 0.52 fx), so a square grid cell images as a rectangle ``dx`` by ``dy`` px with
``dy / dx`` = pixel aspect x cell aspect. kisscal therefore

* builds the primary grid as the thesis does, with one spacing per axis measured at the
  dot nearest the grid centre (``dx`` from its left/right neighbours, ``dy`` from those
  above/below);
* carries out the similarity of eq. 2.1 in the square-pixel frame (``v`` divided by the
  pixel aspect ``a``) and maps the result back, i.e. ``optimal = A S A⁻¹ primary`` with
  ``A = diag(1, a)``;
* fits ``a`` by least squares together with the similarity (closed form for each ``a``,
  a bounded 1-D search over ``a``), because the two central spacings measure it only to
  a few 0.1 %, which would tilt the corrected frame by up to 0.5 px at the field edge.

With square pixels and ``pixel_aspect=1`` this is exactly eq. 2.1. The ``homography``
model (beyond the seeds) replaces ``A S`` by a plane projective map, for a grid that is
not square to the camera: its perspective then stays out of the polynomial.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, minimize_scalar

from kisscal._shared import apply_transform, rms_px, similarity_normaliser
from kisscal.errors import EstimationFailed
from kisscal.grid.lattice import LatticeIndex
from kisscal.grid.params import GridParams


@dataclass(frozen=True, eq=False)
class PrimaryGrid:
    """The primary grid of Küçük 2005, section 2.2.

    Attributes
    ----------
    center_uv : ndarray, shape (2,)
        Position (px) of the dot nearest the centre of the distorted grid.
    spacing_u_px, spacing_v_px : float
        Mean distance to its left/right and to its upper/lower neighbours, px.
    uv : ndarray, shape (N, 2)
        Primary-grid position of each indexed dot (order of the indexed input dots).
    """

    center_uv: NDArray[np.float64]
    spacing_u_px: float
    spacing_v_px: float
    uv: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class OptimalGrid:
    """The optimal grid: the best transform of the primary grid onto the distorted grid.

    Attributes
    ----------
    model : str
        ``"similarity"`` or ``"homography"``.
    matrix : ndarray, shape (3, 3)
        Homogeneous map from square-frame primary-grid coordinates ``g`` (px, relative to
        the centre dot, see :func:`square_frame`) to optimal-grid pixels.
    pixel_aspect : float or None
        Fitted (or given) pixel aspect ``a`` of the similarity model; None for a homography.
    uv : ndarray, shape (N, 2)
        Optimal-grid position of each indexed dot, px.
    rms_px : float
        RMS distance of the distorted dots to the optimal grid (the residual before
        linearisation).
    """

    model: str
    matrix: NDArray[np.float64]
    pixel_aspect: float | None
    uv: NDArray[np.float64]
    rms_px: float


def _lookup(index: LatticeIndex) -> NDArray[np.int64]:
    """(rows, cols) table of input-dot numbers, -1 where no dot."""
    table = np.full((index.rows, index.cols), -1, dtype=np.int64)
    ok = np.flatnonzero(index.indexed)
    table[index.row[ok], index.col[ok]] = ok
    return table


def primary_grid(dots_uv: ArrayLike, index: LatticeIndex) -> PrimaryGrid:
    """Form the primary grid (Küçük 2005, section 2.2).

    The dot nearest the centre of the distorted grid (among those with all four
    neighbours) keeps its position; the general horizontal and vertical spacings are the
    means of the distances to its left/right and upper/lower neighbours, where lens
    distortion is smallest; every other dot is placed at those spacings from it.

    Parameters
    ----------
    dots_uv : array_like, shape (N, 2)
        Detected dots (the same array that was indexed), px.
    index : LatticeIndex
        Their lattice positions.

    Returns
    -------
    PrimaryGrid
        Its ``uv`` follows the order of ``np.flatnonzero(index.indexed)``.
    """
    pts = np.asarray(dots_uv, dtype=float)
    table = _lookup(index)
    ok = np.flatnonzero(index.indexed)
    centre = pts[ok].mean(axis=0)
    order = ok[np.argsort(np.linalg.norm(pts[ok] - centre, axis=1))]
    for i in order:
        r, c = int(index.row[i]), int(index.col[i])
        if 0 < r < index.rows - 1 and 0 < c < index.cols - 1:
            nb = table[[r, r, r - 1, r + 1], [c - 1, c + 1, c, c]]
            if np.all(nb >= 0):
                break
    else:
        raise EstimationFailed("no grid dot has all four neighbours: cannot form the primary grid")
    left, right, up, down = pts[nb]
    dx = 0.5 * (np.linalg.norm(pts[i] - left) + np.linalg.norm(right - pts[i]))
    dy = 0.5 * (np.linalg.norm(pts[i] - up) + np.linalg.norm(down - pts[i]))
    uv = np.column_stack(
        [pts[i, 0] + (index.col[ok] - c) * dx, pts[i, 1] + (index.row[ok] - r) * dy]
    )
    return PrimaryGrid(pts[i].copy(), float(dx), float(dy), uv)


def square_frame(primary: PrimaryGrid, cell_aspect: float = 1.0) -> NDArray[np.float64]:
    """Primary grid in the square-pixel frame: ``g = ((col - c0) dx, (row - r0) dx k)``.

    ``k`` is the grid's cell aspect (row pitch / column pitch, 1 for square cells), so
    ``g`` is the physical grid in units of the central column spacing.
    """
    rel = primary.uv - primary.center_uv
    g = rel.copy()
    g[:, 1] = rel[:, 1] / primary.spacing_v_px * primary.spacing_u_px * cell_aspect
    return g


def _similarity_for_aspect(
    g: NDArray[np.float64], d: NDArray[np.float64], aspect: float
) -> tuple[NDArray[np.float64], float]:
    """Closed-form least squares of ``u = p gx - q gy + tu``, ``v = a (q gx + p gy) + tv``.

    Linear in (p, q, tu, tv) for a fixed pixel aspect ``a``; returns them and the SSE.
    """
    n = len(g)
    m = np.zeros((2 * n, 4))
    m[:n, 0], m[:n, 1], m[:n, 2] = g[:, 0], -g[:, 1], 1.0
    m[n:, 0], m[n:, 1], m[n:, 3] = aspect * g[:, 1], aspect * g[:, 0], 1.0
    rhs = np.concatenate([d[:, 0], d[:, 1]])
    sol, *_ = np.linalg.lstsq(m, rhs, rcond=None)
    return sol, float(np.sum((m @ sol - rhs) ** 2))


def _apply_h(h: NDArray[np.float64], g: NDArray[np.float64]) -> NDArray[np.float64]:
    w = g @ h[:2, :2].T + h[:2, 2]
    den = g @ h[2, :2] + h[2, 2]
    return w / den[:, None]


def _fit_homography(g: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Homography g -> d: normalised linear DLT, then geometric least squares."""

    tg, td = similarity_normaliser(g), similarity_normaliser(d)
    gn, dn = apply_transform(tg, g), apply_transform(td, d)
    n = len(g)
    a = np.zeros((2 * n, 9))
    one = np.ones(n)
    a[:n, 0:3] = np.column_stack([gn, one])
    a[:n, 6:9] = -dn[:, :1] * np.column_stack([gn, one])
    a[n:, 3:6] = np.column_stack([gn, one])
    a[n:, 6:9] = -dn[:, 1:] * np.column_stack([gn, one])
    _, _, vt = np.linalg.svd(a, full_matrices=False)
    hn = vt[-1].reshape(3, 3)
    h = np.linalg.solve(td, hn @ tg)
    h /= h[2, 2]

    def resid(x):
        return (_apply_h(np.append(x, 1.0).reshape(3, 3), g) - d).ravel()

    sol = least_squares(resid, h.ravel()[:8], method="lm", xtol=1e-14, ftol=1e-14)
    return np.append(sol.x, 1.0).reshape(3, 3)


def optimal_grid(
    primary: PrimaryGrid, dots_uv: ArrayLike, index: LatticeIndex, params: GridParams | None = None
) -> OptimalGrid:
    """Least-squares optimal grid (Küçük 2005, section 2.2, eq. 2.1).

    Parameters
    ----------
    primary : PrimaryGrid
        From :func:`primary_grid`.
    dots_uv : array_like, shape (N, 2)
        The detected dots, px (same array as indexed).
    index : LatticeIndex
        Their lattice positions.
    params : GridParams, optional
        ``model``, ``pixel_aspect`` and ``cell_aspect``.

    Returns
    -------
    OptimalGrid
        Transform and optimal position of each indexed dot.
    """
    p = params or GridParams()
    d = np.asarray(dots_uv, dtype=float)[index.indexed]
    g = square_frame(primary, p.cell_aspect)
    a0 = primary.spacing_v_px / primary.spacing_u_px / p.cell_aspect
    if p.model == "similarity":
        if p.pixel_aspect is not None:
            aspect = float(p.pixel_aspect)
        else:
            res = minimize_scalar(
                lambda la: _similarity_for_aspect(g, d, np.exp(la))[1],
                bounds=(np.log(a0) - 0.2, np.log(a0) + 0.2),
                method="bounded",
                options={"xatol": 1e-10},
            )
            aspect = float(np.exp(res.x))
        (pp, qq, tu, tv), _ = _similarity_for_aspect(g, d, aspect)
        matrix = np.array([[pp, -qq, tu], [aspect * qq, aspect * pp, tv], [0.0, 0.0, 1.0]])
        pixel_aspect: float | None = aspect
    else:
        if len(d) < 8:
            raise EstimationFailed("a homography optimal grid needs at least 8 dots")
        matrix = _fit_homography(g, d)
        pixel_aspect = None
    uv = _apply_h(matrix, g)
    rms = rms_px(d - uv)
    return OptimalGrid(p.model, matrix, pixel_aspect, uv, rms)
