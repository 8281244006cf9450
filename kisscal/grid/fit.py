"""From indexed grid dots to the 30 linearisation parameters (Küçük 2005, section 2.2)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import InputError
from kisscal.grid.lattice import LatticeIndex, index_lattice
from kisscal.grid.optimal import OptimalGrid, optimal_grid, primary_grid
from kisscal.grid.params import GridParams
from kisscal.grid.poly import (
    Linearisation,
    LinearisationQuality,
    anchor_affine,
    apply_linearisation,
    compose_affine,
    fit_polynomial,
    poly_terms,
)
from kisscal.grid.quality import leave_rows_out_rms, rms_px, straightness_rms


@dataclass(frozen=True, eq=False)
class GridFit:
    """Everything a grid linearisation produced, for the parameter file and the figures.

    Attributes
    ----------
    linearisation : Linearisation
        The 30 coefficients, normalisation and quality figures.
    index : LatticeIndex
        Row/column of each detected dot, missing positions, rejected blobs.
    optimal : OptimalGrid
        The optimal grid of Küçük 2005, section 2.2 (fitted to the primary grid).
    dots_uv : ndarray, shape (N, 2)
        The detected dots as given (all of them, including rejected blobs), px.
    params : GridParams
        The parameters of the fit (warning limits included).
    """

    linearisation: Linearisation
    index: LatticeIndex
    optimal: OptimalGrid
    dots_uv: NDArray[np.float64]
    params: GridParams = field(default_factory=GridParams)

    @property
    def grid_uv(self) -> NDArray[np.float64]:
        """The indexed (distorted) dots, in the order of ``optimal.uv``."""
        return self.dots_uv[self.index.indexed]

    @property
    def corrected_uv(self) -> NDArray[np.float64]:
        """The indexed dots after linearisation."""
        return apply_linearisation(self.linearisation, self.grid_uv)

    def warnings(self) -> list[str]:
        """One-line warnings a technician should read before using this linearisation
        (limits ``warn_residual_px`` and ``warn_cv_ratio`` of :class:`GridParams`)."""
        max_residual_px = self.params.warn_residual_px
        max_cv_ratio = self.params.warn_cv_ratio
        q = self.linearisation.quality
        out = []
        if q is None:
            return out
        if q.dots_missing:
            where = ", ".join(f"({r},{c})" for r, c in self.index.missing_rc[:8])
            more = " ..." if q.dots_missing > 8 else ""
            out.append(f"{q.dots_missing} grid dots missing at (row,col) {where}{more}")
        if q.blobs_rejected:
            out.append(f"{q.blobs_rejected} blobs were not grid dots and were ignored")
        if q.residual_rms_after_px > max_residual_px:
            out.append(
                f"grid residual {q.residual_rms_after_px:.3f} px RMS exceeds "
                f"{max_residual_px} px: check focus and dot detection"
            )
        if q.cv_rms_px > max_cv_ratio * q.residual_rms_after_px:
            out.append(
                f"leave-one-row-out residual {q.cv_rms_px:.3f} px is more than {max_cv_ratio:g}x "
                f"the fit residual {q.residual_rms_after_px:.3f} px: the polynomial may be "
                "over-fitting; use a grid that fills the view"
            )
        return out


def normalisation(
    dots_uv: ArrayLike, size_px: tuple[int, int] | None = None
) -> tuple[tuple[float, float], float]:
    """Centre and scale of the normalised coordinates (DESIGN.md).

    With the image size, the centre is the image centre ``((w - 1) / 2, (h - 1) / 2)`` and
    the scale half the larger side, so the whole field of view maps into [-1, 1]; without
    it, the centre and half the larger extent of the dots.
    """
    if size_px is not None:
        w, h = size_px
        if not (w > 0 and h > 0):
            raise InputError(f"image size must be positive, got {size_px}")
        return ((w - 1) / 2.0, (h - 1) / 2.0), max(w, h) / 2.0
    pts = np.asarray(dots_uv, dtype=float)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = (lo + hi) / 2
    return (float(c[0]), float(c[1])), float(max(hi - lo) / 2)


def _reframe(optimal: OptimalGrid, m: NDArray[np.float64], grid: NDArray[np.float64]):
    """The optimal grid mapped by the plane projective map ``m`` (3 x 3, px to px)."""
    matrix = m @ optimal.matrix
    uv = optimal.uv @ m[:2, :2].T + m[:2, 2]
    uv = uv / (optimal.uv @ m[2, :2] + m[2, 2])[:, None]
    aspect = optimal.pixel_aspect
    if aspect is not None:
        aspect = float(np.linalg.norm(matrix[1, :2]) / np.linalg.norm(matrix[0, :2]))
    return replace(optimal, matrix=matrix, pixel_aspect=aspect, uv=uv, rms_px=rms_px(grid - uv))


def _perspective_matrix(
    eps: NDArray[np.float64], centre: tuple[float, float], scale: float
) -> NDArray[np.float64]:
    """``y -> c + (y - c) / (1 + eps · (y - c) / s)``: pure perspective about the centre."""
    t = np.array([[1.0, 0.0, centre[0]], [0.0, 1.0, centre[1]], [0.0, 0.0, 1.0]])
    k = np.eye(3)
    k[2, :2] = np.asarray(eps) / scale
    return t @ k @ np.linalg.inv(t)


# 2nd-order patterns of a plane map in the square-pixel frame, as coefficients of
# (du: x², xy, y²; dv: x², xy, y²). Perspective (eps1, eps2) of the grid plane moves a point
# e by -(eps·e) e; decentring of the lens (tangential distortion p1, p2, or radial
# distortion about a point off the centre, which has the same form) by
# (q1 (3x² + y²) + 2 q2 xy, q2 (x² + 3y²) + 2 q1 xy).
N_PERSPECTIVE_TERMS = 10
_SECOND_ORDER = np.array(
    [
        [-1, 0, 0, 0, -1, 0],  # perspective eps1
        [0, -1, 0, 0, 0, -1],  # perspective eps2
        [3, 0, 1, 0, 2, 0],  # decentring q1
        [0, 2, 0, 1, 0, 3],  # decentring q2
    ],
    dtype=float,
).T


def _lens_centre_perspective(
    grid: NDArray[np.float64],
    optimal_uv: NDArray[np.float64],
    centre: tuple[float, float],
    scale: float,
    aspect: float,
) -> NDArray[np.float64]:
    """Perspective (2 numbers) to add to a homography optimal grid so that the anchored
    lens correction has no perspective-shaped 2nd-order terms at the centre.

    From a single planar view the perspective of the grid and the quadratic part of the
    lens correction are interchangeable up to 4th order, so the data cannot separate
    them; the least-squares homography settles it by where the distortion happens to
    fall (and moves by up to 0.1 px with the subset of dots found). In the Brown lens
    model the 2nd-order terms at a point near the lens centre are decentring-shaped
    (tangential distortion, or radial distortion about a slightly different centre),
    which differs from the perspective shape. Decomposing the correction's quadratic
    coefficients (in the square-pixel frame, ``v`` divided by the pixel aspect) into the
    two shapes and asking for no perspective part pins the grid's perspective down.
    """
    to_square = np.array(
        [1.0, aspect, aspect**2, 1.0 / aspect, 1.0, aspect]
    )  # un^i vn^j with vn = aspect * y; dv divided by aspect
    # Terms up to N_PERSPECTIVE_TERMS only: the quadratic coefficients of a cubic fit are
    # less noisy than those of the quartic one, and lens quartic terms are small.
    z = poly_terms((grid[:, 0] - centre[0]) / scale, (grid[:, 1] - centre[1]) / scale)
    z = z[:, :N_PERSPECTIVE_TERMS]

    def perspective_part(eps: NDArray[np.float64]) -> NDArray[np.float64]:
        m = _perspective_matrix(eps, centre, scale)
        target = optimal_uv @ m[:2, :2].T + m[:2, 2]
        target = target / (optimal_uv @ m[2, :2] + m[2, 2])[:, None]
        coef, *_ = np.linalg.lstsq(z, target, rcond=None)
        # At the normalisation centre the linear coefficients are the Jacobian (x s);
        # anchoring multiplies the quadratic ones by its inverse.
        quad = (np.linalg.inv(coef[1:3].T) @ coef[3:6].T).ravel() * to_square
        shape, *_ = np.linalg.lstsq(_SECOND_ORDER, quad, rcond=None)
        return shape[:2]

    eps = np.zeros(2)
    h = 1e-4
    for _ in range(5):
        r0 = perspective_part(eps)
        jac = np.column_stack([(perspective_part(eps + h * e) - r0) / h for e in np.eye(2)])
        step, *_ = np.linalg.lstsq(jac, -r0, rcond=None)
        eps = eps + step
        if np.abs(step).max() < 1e-10:
            break
    return eps


def fit_linearisation(
    dots_uv: ArrayLike,
    index: LatticeIndex,
    params: GridParams | None = None,
    size_px: tuple[int, int] | None = None,
) -> GridFit:
    """Fit the 15 + 15 linearisation coefficients to indexed grid dots.

    The three steps of Küçük 2005, section 2.2: primary grid, least-squares optimal grid
    (eq. 2.1; see :mod:`kisscal.grid.optimal` for non-square pixels and the homography
    option), then the 4th-order polynomial from distorted to optimal grid (eqs. 2.2-2.4),
    solved on normalised coordinates by SVD least squares.

    Parameters
    ----------
    dots_uv : array_like, shape (N, 2)
        Detected dots, px (the array given to :func:`index_lattice`).
    index : LatticeIndex
        Their lattice positions.
    params : GridParams, optional
        Optimal-grid model and aspects.
    size_px : (int, int), optional
        Image width and height, px: sets the normalisation to the whole field of view.

    Returns
    -------
    GridFit
        Coefficients with quality figures, and the intermediate grids.
    """
    p = params or GridParams()
    pts = np.asarray(dots_uv, dtype=float)
    primary = primary_grid(pts, index)
    optimal = optimal_grid(primary, pts, index, p)
    grid = pts[index.indexed]
    centre, scale = normalisation(grid, size_px)
    if p.model == "homography" and p.perspective == "lens_centre":
        aspect = primary.spacing_v_px / primary.spacing_u_px / p.cell_aspect
        eps = _lens_centre_perspective(grid, optimal.uv, centre, scale, aspect)
        optimal = _reframe(optimal, _perspective_matrix(eps, centre, scale), grid)
    lin = fit_polynomial(grid, optimal.uv, centre, scale)
    if p.anchor_centre:
        # Same affine map on the polynomial and on the optimal grid: residuals unchanged
        # in meaning, the corrected frame now matches the lens centre's (see GridParams).
        a = anchor_affine(lin, centre)
        lin = compose_affine(a, lin)
        optimal = _reframe(optimal, a, grid)
    corrected = apply_linearisation(lin, grid)
    res = np.linalg.norm(corrected - optimal.uv, axis=1)
    row, col = index.row[index.indexed], index.col[index.indexed]
    quality = LinearisationQuality(
        optimal_model=p.model,
        pixel_aspect=optimal.pixel_aspect,
        rows=index.rows,
        cols=index.cols,
        dots_used=len(grid),
        dots_missing=len(index.missing_rc),
        blobs_rejected=len(index.rejected),
        residual_rms_before_px=optimal.rms_px,
        residual_rms_after_px=rms_px(corrected - optimal.uv),
        residual_max_after_px=float(res.max()),
        straightness_rms_before_px=straightness_rms(grid, row, col),
        straightness_rms_after_px=straightness_rms(corrected, row, col),
        cv_rms_px=leave_rows_out_rms(grid, optimal.uv, row, centre, scale),
    )
    lin = Linearisation(lin.center_px, lin.scale_px, lin.x, lin.y, quality)
    return GridFit(lin, index, optimal, pts, p)


def linearise_dots(
    dots_uv: ArrayLike, params: GridParams | None = None, size_px: tuple[int, int] | None = None
) -> GridFit:
    """Index detected grid dots and fit the linearisation: the whole stage on 2D dots.

    Parameters
    ----------
    dots_uv : array_like, shape (N, 2)
        Blob centroids detected in the (averaged) grid image, px.
    params : GridParams, optional
        Grid size, model and tolerances.
    size_px : (int, int), optional
        Image width and height, px.

    Returns
    -------
    GridFit
    """
    p = params or GridParams()
    index = index_lattice(dots_uv, p)
    return fit_linearisation(dots_uv, index, p, size_px)
