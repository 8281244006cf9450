"""Quality figures of a linearisation: straightness of grid lines, residuals, cross-validation."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import rms_px
from kisscal.grid.poly import apply_linearisation, fit_polynomial


def line_distances(uv: ArrayLike, line: ArrayLike) -> NDArray[np.float64]:
    """Signed distance of each point to the total-least-squares line through its group.

    Parameters
    ----------
    uv : array_like, shape (N, 2)
        Points, px.
    line : array_like of int, shape (N,)
        Group (grid row or column number) of each point; groups with fewer than three
        points get NaN (two points always lie on a line).

    Returns
    -------
    ndarray, shape (N,)
        Distance to the group's line, px.
    """
    pts = np.asarray(uv, dtype=float)
    g = np.asarray(line)
    _, inv, counts = np.unique(g, return_inverse=True, return_counts=True)
    n = counts.astype(float)
    mean = np.column_stack([np.bincount(inv, pts[:, 0]) / n, np.bincount(inv, pts[:, 1]) / n])
    rel = pts - mean[inv]
    sxx = np.bincount(inv, rel[:, 0] ** 2)
    syy = np.bincount(inv, rel[:, 1] ** 2)
    sxy = np.bincount(inv, rel[:, 0] * rel[:, 1])
    # Line direction = principal axis of each group's scatter (closed form for 2 x 2).
    theta = 0.5 * np.arctan2(2 * sxy, sxx - syy)
    normal = np.column_stack([-np.sin(theta), np.cos(theta)])
    dist = np.sum(rel * normal[inv], axis=1)
    dist[counts[inv] < 3] = np.nan
    return dist


def straightness_rms(uv: ArrayLike, row: ArrayLike, col: ArrayLike) -> float:
    """RMS distance of grid dots to straight lines fitted to every row and every column.

    The deviation of the grid lines from straightness is what the linearisation removes
    (Shafiq et al. 2001, section 3.2); it needs no optimal grid, so it judges the
    correction independently of the similarity/homography choice.

    Parameters
    ----------
    uv : array_like, shape (N, 2)
        Dot positions, px.
    row, col : array_like of int, shape (N,)
        Their lattice positions.

    Returns
    -------
    float
        RMS over all row-line and column-line distances, px.
    """
    d = np.concatenate([line_distances(uv, row), line_distances(uv, col)])
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d * d))) if len(d) else float("nan")


def straightness_noise_floor_px(noise_px: float, row: ArrayLike, col: ArrayLike) -> float:
    """Expected :func:`straightness_rms` of perfectly straight grid lines carrying noise.

    With independent centroid noise of ``noise_px`` per coordinate, the perpendicular
    distance of a dot to the least-squares line through the n dots of its row (or column)
    has expected square ``noise_px² (n - 2) / n``: the line's two parameters absorb two
    of the n degrees of freedom. No linearisation can bring the corrected grid's
    straightness below this floor, so the before/after ratio is bounded by
    ``before / floor`` however good the lens model is (15 x 20 grid: floor = 0.94 noise).

    Parameters
    ----------
    noise_px : float
        Centroid noise, standard deviation per coordinate, px.
    row, col : array_like of int, shape (N,)
        Lattice positions of the dots (lines with fewer than three dots are skipped, as in
        :func:`straightness_rms`).

    Returns
    -------
    float
        Expected straightness RMS, px.
    """
    factors = []
    for group in (np.asarray(row), np.asarray(col)):
        _, inv, counts = np.unique(group, return_inverse=True, return_counts=True)
        n = counts[inv].astype(float)
        factors.append(((n - 2) / n)[n >= 3])
    f = np.concatenate(factors)
    return float(noise_px * np.sqrt(np.mean(f))) if len(f) else float("nan")


def leave_rows_out_rms(
    distorted_uv: ArrayLike,
    optimal_uv: ArrayLike,
    row: ArrayLike,
    center_px: tuple[float, float],
    scale_px: float,
) -> float:
    """Leave-one-row-out cross-validation residual of the polynomial fit, px.

    Each grid row in turn is left out, the 15 + 15 coefficients are fitted to the other
    rows (optimal grid kept), and the left-out row is predicted. The outer rows are
    extrapolations, so this is a pessimistic figure; a value many times the fit residual
    warns that the polynomial follows noise rather than the lens.
    """
    d = np.asarray(distorted_uv, dtype=float)
    t = np.asarray(optimal_uv, dtype=float)
    r = np.asarray(row)
    errs = []
    for k in np.unique(r):
        out = r == k
        if np.count_nonzero(~out) < 30:
            continue
        lin = fit_polynomial(d[~out], t[~out], center_px, scale_px)
        errs.append(apply_linearisation(lin, d[out]) - t[out])
    return rms_px(np.concatenate(errs)) if errs else float("nan")
