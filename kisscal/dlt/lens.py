"""Brown's lens model, written once: distortion, its Jacobian and its inverse.

Brown's distortion (Brown 1966, 1971) in OpenCV's order and convention (Bradski 2000):
radial ``k1 k2 p1 p2 k3``, then the rational model's ``k4 k5 k6`` and the thin prism's
``s1 s2 s3 s4``. :class:`kisscal.camera.Camera` applies it to normalised coordinates (the
bundle adjustment, the synthetic rigs and the OpenCV exports through it); the DLT's lens
terms L12..L16 (Kolahi et al. 2007, eq. 2, :func:`kisscal.dlt.nonlinear.lens_offsets`)
are the same polynomial in the DLT's square pixels, written as the DLT literature writes
it (``dlt_form``): the displacement alone, and the decentering's cross terms ``x y`` at
half Brown's weight. It lives in the DLT package because both the camera and the DLT's
solvers use it, and the camera already stands on the DLT.

References
----------
Bradski, G. (2000). The OpenCV library. Dr. Dobb's Journal of Software Tools.
Brown, D. C. (1966). Decentering distortion of lenses. Photogrammetric Engineering 32(3).
Brown, D. C. (1971). Close-range camera calibration. Photogrammetric Engineering 37(8).
Kolahi, A., Hoviattalab, M., Rezaeian, T., Alizadeh, M., Bostan, M., & Mokhtarzadeh, H.
(2007). Design of a marker-based human motion tracking system. Biomedical Signal
Processing and Control, 2, 59-67.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def _terms(lens: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """The twelve coefficients of one lens (shape (k,)) or one per row (shape (n, k))."""
    d = np.asarray(lens, dtype=float)
    if d.ndim == 1:  # scalars: the same products as 0-d arrays, without their overhead
        full = np.zeros(12)
        full[: d.size] = d
        return tuple(full)
    pad = np.zeros((*d.shape[:-1], 12 - d.shape[-1]))
    d = np.concatenate([d, pad], axis=-1)
    return tuple(d[..., i] for i in range(12))


def _radial(
    terms: tuple[NDArray[np.float64], ...],
    r2: NDArray[np.float64],
    rational: bool,
    one: float,
    slope: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The radial factor ``ρ`` (``one`` + the series) and ``dρ / d(r²)`` (None without
    ``slope``: the distortion alone needs no derivative)."""
    k1, k2, _, _, k3, k4, k5, k6 = terms[:8]
    radial = one + r2 * (k1 + r2 * (k2 + r2 * k3))
    if not slope:
        return (radial / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))) if rational else radial), None
    d_radial = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)
    if rational:
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        d_den = k4 + r2 * (2.0 * k5 + 3.0 * k6 * r2)
        d_radial = (d_radial * den - radial * d_den) / den**2
        radial = radial / den
    return radial, d_radial


def distort(lens: ArrayLike, xn: ArrayLike) -> NDArray[np.float64]:
    """Brown's distortion of normalised coordinates, OpenCV's convention.

    Parameters
    ----------
    lens : array_like, shape (k,) or (n, k)
        One lens for every point, or one per row; ``k`` is 4, 5, 8 or 12
        (``k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4]]]``).
    xn : array_like, shape (..., 2)
        Undistorted normalised coordinates.

    Returns
    -------
    ndarray, shape (..., 2)
        ``x ρ + 2 p1 x y + p2 (r² + 2 x²) + s1 r² + s2 r⁴`` and
        ``y ρ + p1 (r² + 2 y²) + 2 p2 x y + s3 r² + s4 r⁴`` with
        ``ρ = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)``.
    """
    xn = np.asarray(xn, dtype=float)
    return np.stack(distort_xy(lens, xn[..., 0], xn[..., 1]), axis=-1)


def distort_xy(
    lens: ArrayLike, x: NDArray[np.float64], y: NDArray[np.float64], dlt_form: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`distort` of coordinates given as ``x`` and ``y`` apart, returned apart: the
    same numbers without stacking them (the DLT's lens terms, evaluated thousands of
    times a fit on a few dozen points, :func:`kisscal.dlt.nonlinear.lens_offsets`).
    ``dlt_form`` gives the DLT literature's form (Kolahi et al. 2007, eq. 2): the displacement
    alone (``ρ - 1`` for ``ρ``) and ``p1 x y``, ``p2 x y`` for ``2 p1 x y``, ``2 p2 x y``."""
    terms = _terms(lens)
    p1, p2, s1, s2, s3, s4 = terms[2], terms[3], *terms[8:]
    rational = np.shape(lens)[-1] > 5  # the rational model and the thin prism
    r2 = x * x + y * y
    radial, _ = _radial(terms, r2, rational, 0.0 if dlt_form else 1.0, slope=False)
    cross = 1.0 if dlt_form else 2.0
    xd = x * radial + cross * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + cross * p2 * x * y
    if rational:
        xd = xd + r2 * (s1 + s2 * r2)
        yd = yd + r2 * (s3 + s4 * r2)
    return xd, yd


def distort_each(lens: ArrayLike, xn: ArrayLike, moved: ArrayLike) -> NDArray[np.float64]:
    """:func:`distort` of one lens with one coefficient moved at a time, bit for bit.

    Parameters
    ----------
    lens : array_like, shape (k,)
        One lens (``k`` 4, 5, 8 or 12, as :func:`distort`).
    xn : array_like, shape (n, 2)
        Undistorted normalised coordinates.
    moved : array_like, shape (k,)
        The value each coefficient moves to.

    Returns
    -------
    ndarray, shape (k, n, 2)
        Row ``c``: ``distort(lens with lens[c] = moved[c], xn)``, the same numbers: each
        term is computed as :func:`distort` computes it, and only those coefficient ``c``
        enters are computed again (the columns of a forward-difference Jacobian).
    """
    xn = np.asarray(xn, dtype=float)
    k0 = list(_terms(lens))
    rational = np.shape(lens)[-1] > 5
    x, y = xn[..., 0], xn[..., 1]
    r2 = x * x + y * y
    qx, qy = r2 + 2.0 * x * x, r2 + 2.0 * y * y

    def terms(k: list, c: int | None) -> dict[str, NDArray[np.float64]]:
        """The terms of ``xd`` (x..) and ``yd`` (y..) that coefficient ``c`` enters
        (all of them for None)."""
        out = {}
        if c is None or c in (0, 1, 4, 5, 6, 7):
            r, _ = _radial(tuple(k), r2, rational, 1.0)
            out.update(xr=x * r, yr=y * r)
        if c is None or c == 2:
            out.update(xp1=2.0 * k[2] * x * y, yp1=k[2] * qy)
        if c is None or c == 3:
            out.update(xp2=k[3] * qx, yp2=2.0 * k[3] * x * y)
        if rational and (c is None or c in (8, 9)):
            out["xs"] = r2 * (k[8] + k[9] * r2)
        if rational and (c is None or c in (10, 11)):
            out["ys"] = r2 * (k[10] + k[11] * r2)
        return out

    base = terms(k0, None)
    result = np.empty((np.shape(lens)[-1], *x.shape, 2))
    for c, value in enumerate(np.asarray(moved, dtype=float)):
        k = list(k0)
        k[c] = value
        t = {**base, **terms(k, c)}
        result[c, ..., 0] = t["xr"] + t["xp1"] + t["xp2"]
        result[c, ..., 1] = t["yr"] + t["yp1"] + t["yp2"]
        if rational:
            result[c, ..., 0] += t["xs"]
            result[c, ..., 1] += t["ys"]
    return result


def distortion_jacobian(lens: ArrayLike, xn: ArrayLike) -> NDArray[np.float64]:
    """``d(xd, yd) / d(x, y)`` of :func:`distort`, shape (..., 2, 2)."""
    xn = np.asarray(xn, dtype=float)
    terms = _terms(lens)
    p1, p2, s1, s2, s3, s4 = terms[2], terms[3], *terms[8:]
    rational = np.shape(lens)[-1] > 5
    x, y = xn[..., 0], xn[..., 1]
    r2 = x * x + y * y
    radial, d_radial = _radial(terms, r2, rational, 1.0)
    prism_x = prism_y = 0.0
    if rational:
        prism_x, prism_y = s1 + 2.0 * s2 * r2, s3 + 2.0 * s4 * r2  # d prism / d r²
    jac = np.empty((*x.shape, 2, 2))
    jac[..., 0, 0] = radial + 2 * x * x * d_radial + 2 * p1 * y + 6 * p2 * x + 2 * x * prism_x
    jac[..., 0, 1] = 2 * x * y * d_radial + 2 * p1 * x + 2 * p2 * y + 2 * y * prism_x
    jac[..., 1, 0] = 2 * x * y * d_radial + 2 * p1 * x + 2 * p2 * y + 2 * x * prism_y
    jac[..., 1, 1] = radial + 2 * y * y * d_radial + 6 * p1 * y + 2 * p2 * x + 2 * y * prism_y
    return jac


def undistort(lens: ArrayLike, xd: ArrayLike, tol: float = 1e-14) -> NDArray[np.float64]:
    """Inverse of :func:`distort` by Newton's method (to ``tol``, at most 100 steps).

    OpenCV's own ``undistortPoints`` stops after 5 fixed-point steps by default, too coarse
    for a round trip; Newton's method converges to rounding for the lenses of a lab.
    """
    xd = np.asarray(xd, dtype=float)
    x = xd.copy()
    for _ in range(100):
        err = distort(lens, x) - xd
        D = distortion_jacobian(lens, x)
        det = D[..., 0, 0] * D[..., 1, 1] - D[..., 0, 1] * D[..., 1, 0]
        step = np.stack(
            [
                (D[..., 1, 1] * err[..., 0] - D[..., 0, 1] * err[..., 1]) / det,
                (D[..., 0, 0] * err[..., 1] - D[..., 1, 0] * err[..., 0]) / det,
            ],
            axis=-1,
        )
        x -= step
        if np.max(np.abs(step), initial=0.0) < tol:
            break
    return x
