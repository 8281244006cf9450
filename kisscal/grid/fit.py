"""From indexed grid dots to the 30 linearisation parameters (Küçük 2005, section 2.2)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import KisscalError
from kisscal.grid.lattice import LatticeIndex, index_lattice
from kisscal.grid.optimal import OptimalGrid, PrimaryGrid, optimal_grid, primary_grid
from kisscal.grid.params import GridParams
from kisscal.grid.poly import (
    Linearisation,
    LinearisationQuality,
    anchor_affine,
    apply_linearisation,
    compose_affine,
    fit_polynomial,
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
    primary, optimal : PrimaryGrid, OptimalGrid
        The two reference grids of Küçük 2005, section 2.2.
    dots_uv : ndarray, shape (N, 2)
        The detected dots as given (all of them, including rejected blobs), px.
    """

    linearisation: Linearisation
    index: LatticeIndex
    primary: PrimaryGrid
    optimal: OptimalGrid
    dots_uv: NDArray[np.float64]

    @property
    def grid_uv(self) -> NDArray[np.float64]:
        """The indexed (distorted) dots, in the order of ``optimal.uv``."""
        return self.dots_uv[self.index.indexed]

    @property
    def corrected_uv(self) -> NDArray[np.float64]:
        """The indexed dots after linearisation."""
        return apply_linearisation(self.linearisation, self.grid_uv)


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
            raise KisscalError(f"image size must be positive, got {size_px}")
        return ((w - 1) / 2.0, (h - 1) / 2.0), max(w, h) / 2.0
    pts = np.asarray(dots_uv, dtype=float)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    c = (lo + hi) / 2
    return (float(c[0]), float(c[1])), float(max(hi - lo) / 2)


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
    lin = fit_polynomial(grid, optimal.uv, centre, scale)
    if p.anchor_centre:
        # Same affine map on the polynomial and on the optimal grid: residuals unchanged
        # in meaning, the corrected frame now matches the lens centre's (see GridParams).
        a = anchor_affine(lin, centre)
        lin = compose_affine(a, lin)
        matrix = a @ optimal.matrix
        aspect = optimal.pixel_aspect
        if aspect is not None:
            aspect = float(np.linalg.norm(matrix[1, :2]) / np.linalg.norm(matrix[0, :2]))
        uv = optimal.uv @ a[:2, :2].T + a[:2, 2]
        optimal = replace(
            optimal, matrix=matrix, pixel_aspect=aspect, uv=uv, rms_px=rms_px(grid - uv)
        )
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
    return GridFit(lin, index, primary, optimal, pts)


def linearise_dots(
    dots_uv: ArrayLike,
    params: GridParams | None = None,
    size_px: tuple[int, int] | None = None,
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
