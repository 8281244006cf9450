"""The 4th-order linearisation polynomial: terms, least-squares fit, apply and inverse.

Küçük 2005, eq. 2.2: each corrected coordinate is a 15-term polynomial of the distorted
coordinates, in the order 1, u, v, u², uv, v², u³, u²v, uv², v³, u⁴, u³v, u²v², uv³, v⁴.
As DESIGN.md prescribes, the polynomial is evaluated on normalised coordinates
``un = (u - cu) / s``, ``vn = (v - cv) / s`` and returns pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import EstimationFailed, InputError

N_TERMS = 15
TERM_NAMES = (
    "1",
    "u",
    "v",
    "u^2",
    "uv",
    "v^2",
    "u^3",
    "u^2v",
    "uv^2",
    "v^3",
    "u^4",
    "u^3v",
    "u^2v^2",
    "uv^3",
    "v^4",
)
# (power of u, power of v) of each term, in the thesis' order.
TERM_POWERS = np.array([(i - j, j) for i in range(5) for j in range(i + 1)], dtype=int)


@dataclass(frozen=True)
class LinearisationQuality:
    """Quality figures of a fitted linearisation (all distances in px, ``rms_px`` convention).

    Attributes
    ----------
    optimal_model : str
        Optimal-grid transform used ("similarity" or "homography").
    pixel_aspect : float or None
        Pixel height / width of the similarity optimal grid (None for a homography).
    rows, cols : int
        Grid size.
    dots_used : int
        Indexed dots the polynomial was fitted to.
    dots_missing : int
        Grid positions without a dot.
    blobs_rejected : int
        Detected blobs that were not grid dots.
    residual_rms_before_px, residual_rms_after_px : float
        RMS distance of the distorted / corrected dots to the optimal grid.
    residual_max_after_px : float
        Largest distance of a corrected dot to its optimal-grid position.
    straightness_rms_before_px, straightness_rms_after_px : float
        RMS distance of the dots to straight lines fitted to each grid row and column,
        before and after correction.
    cv_rms_px : float
        Leave-one-row-out cross-validation residual: each row predicted by a polynomial
        fitted without it. Much larger than ``residual_rms_after_px`` warns of over-fitting.
    """

    optimal_model: str
    pixel_aspect: float | None
    rows: int
    cols: int
    dots_used: int
    dots_missing: int
    blobs_rejected: int
    residual_rms_before_px: float
    residual_rms_after_px: float
    residual_max_after_px: float
    straightness_rms_before_px: float
    straightness_rms_after_px: float
    cv_rms_px: float


@dataclass(frozen=True, eq=False)
class Linearisation:
    """The 30 linearisation parameters of one camera with their normalisation.

    ``u' = x · t(un, vn)``, ``v' = y · t(un, vn)`` with ``un = (u - cu) / s``,
    ``vn = (v - cv) / s`` (Küçük 2005, eq. 2.2; DESIGN.md).

    Attributes
    ----------
    center_px : tuple of float
        ``(cu, cv)``, the normalisation centre in px.
    scale_px : float
        ``s``, the normalisation scale in px.
    x, y : ndarray, shape (15,)
        Coefficients of the corrected u and v (px), in the thesis' term order.
    quality : LinearisationQuality or None
        Fit quality, when the linearisation was fitted (or read with it).
    """

    center_px: tuple[float, float]
    scale_px: float
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    quality: LinearisationQuality | None = None

    def __post_init__(self) -> None:
        x = np.array(self.x, dtype=float)
        y = np.array(self.y, dtype=float)
        if x.shape != (N_TERMS,) or y.shape != (N_TERMS,):
            raise InputError(
                f"linearisation needs 15 x and 15 y coefficients, got {x.shape} and {y.shape}"
            )
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
            raise InputError("linearisation coefficients must be finite numbers")
        if not (np.isfinite(self.scale_px) and self.scale_px > 0):
            raise InputError(f"linearisation scale_px must be positive, got {self.scale_px}")
        x.setflags(write=False)
        y.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "center_px", (float(self.center_px[0]), float(self.center_px[1])))
        object.__setattr__(self, "scale_px", float(self.scale_px))


def identity_linearisation(center_px: tuple[float, float], scale_px: float) -> Linearisation:
    """The linearisation that leaves every coordinate unchanged (a session without a grid)."""
    x = np.zeros(N_TERMS)
    y = np.zeros(N_TERMS)
    x[0], x[1] = center_px[0], scale_px
    y[0], y[2] = center_px[1], scale_px
    return Linearisation(center_px, scale_px, x, y)


def _as_points(uv: ArrayLike, name: str = "uv") -> NDArray[np.float64]:
    pts = np.asarray(uv, dtype=float)
    if pts.ndim < 1 or pts.shape[-1] != 2:
        raise InputError(f"{name} must have shape (..., 2), got {pts.shape}")
    return pts


def poly_terms(un: ArrayLike, vn: ArrayLike) -> NDArray[np.float64]:
    """The 15 terms of eq. 2.2 at normalised coordinates, shape ``(..., 15)``."""
    un = np.asarray(un, dtype=float)
    vn = np.asarray(vn, dtype=float)
    upow = [np.ones_like(un), un, un * un, un * un * un, (un * un) ** 2]
    vpow = [np.ones_like(vn), vn, vn * vn, vn * vn * vn, (vn * vn) ** 2]
    return np.stack([upow[a] * vpow[b] for a, b in TERM_POWERS], axis=-1)


_CHUNK = 1 << 14  # points per block: keeps the ~10 work arrays inside the CPU cache


def _horner_into(
    c: NDArray[np.float64],
    un: NDArray[np.float64],
    vn: NDArray[np.float64],
    out: NDArray[np.float64],
    tmp: NDArray[np.float64],
) -> None:
    """Evaluate one 15-term polynomial into ``out`` as a polynomial in ``un`` whose
    coefficients are polynomials in ``vn`` (nested Horner, all in place):

    ``((((a4 un + a3) un + a2) un + a1) un + a0``, ``a3 = c6 + c11 v``,
    ``a2 = c3 + (c7 + c12 v) v``, ``a1 = c1 + (c4 + (c8 + c13 v) v) v``,
    ``a0 = c0 + (c2 + (c5 + (c9 + c14 v) v) v) v``, ``a4 = c10``.
    """
    # out = a4 un + a3
    np.multiply(vn, c[11], out=out)
    out += c[6]
    out += c[10] * un
    out *= un
    # + a2
    np.multiply(vn, c[12], out=tmp)
    tmp += c[7]
    tmp *= vn
    tmp += c[3]
    out += tmp
    out *= un
    # + a1
    np.multiply(vn, c[13], out=tmp)
    tmp += c[8]
    tmp *= vn
    tmp += c[4]
    tmp *= vn
    tmp += c[1]
    out += tmp
    out *= un
    # + a0
    np.multiply(vn, c[14], out=tmp)
    tmp += c[9]
    tmp *= vn
    tmp += c[5]
    tmp *= vn
    tmp += c[2]
    tmp *= vn
    tmp += c[0]
    out += tmp


def apply_linearisation(lin: Linearisation, uv: ArrayLike) -> NDArray[np.float64]:
    """Correct distorted pixel coordinates with a linearisation (Küçük 2005, eq. 2.2, 3.3.2).

    Parameters
    ----------
    lin : Linearisation
        Coefficients and normalisation.
    uv : array_like, shape (..., 2)
        Distorted (raw) pixel coordinates, any number of points.

    Returns
    -------
    ndarray, shape (..., 2)
        Linearised pixel coordinates.

    Notes
    -----
    Evaluated by nested Horner in blocks of 16384 points with in-place arithmetic; 1e6
    points take a few tens of milliseconds (``python -m benchmarks grid``).
    """
    pts = _as_points(uv)
    flat = pts.reshape(-1, 2)
    n = len(flat)
    out = np.empty((n, 2), dtype=float)
    m = min(n, _CHUNK)
    un, vn, ou, ov, tmp = (np.empty(m) for _ in range(5))
    cu, cv = lin.center_px
    inv_s = 1.0 / lin.scale_px
    for start in range(0, n, _CHUNK):
        k = min(_CHUNK, n - start)
        block = flat[start : start + k]
        np.subtract(block[:, 0], cu, out=un[:k])
        un[:k] *= inv_s
        np.subtract(block[:, 1], cv, out=vn[:k])
        vn[:k] *= inv_s
        _horner_into(lin.x, un[:k], vn[:k], ou[:k], tmp[:k])
        _horner_into(lin.y, un[:k], vn[:k], ov[:k], tmp[:k])
        out[start : start + k, 0] = ou[:k]
        out[start : start + k, 1] = ov[:k]
    return out.reshape(pts.shape)


def _derivative_matrix(axis: int) -> NDArray[np.float64]:
    """(15, 15) map from coefficients to those of the derivative along ``un`` (0) or ``vn`` (1).

    d/du of u^a v^b is a u^(a-1) v^b, again a term of the thesis' basis (degree <= 3).
    """
    index = {(int(a), int(b)): k for k, (a, b) in enumerate(TERM_POWERS)}
    d = np.zeros((N_TERMS, N_TERMS))
    for k, (a, b) in enumerate(TERM_POWERS):
        power = (a, b)[axis]
        if power > 0:
            lower = (a - 1, b) if axis == 0 else (a, b - 1)
            d[index[lower], k] = power
    return d


_D_UN = _derivative_matrix(0)
_D_VN = _derivative_matrix(1)


def _jacobian(lin: Linearisation, uv: NDArray[np.float64]) -> NDArray[np.float64]:
    """d(u', v') / d(u, v) at ``uv``, shape ``(..., 2, 2)`` (px per px)."""
    d_un = Linearisation(lin.center_px, lin.scale_px, _D_UN @ lin.x, _D_UN @ lin.y)
    d_vn = Linearisation(lin.center_px, lin.scale_px, _D_VN @ lin.x, _D_VN @ lin.y)
    jac = np.stack([apply_linearisation(d_un, uv), apply_linearisation(d_vn, uv)], axis=-1)
    return jac / lin.scale_px


def invert_linearisation(lin: Linearisation, uv: ArrayLike) -> NDArray[np.float64]:
    """Distorted coordinates whose linearisation is ``uv``, by Newton iteration (at most
    30 steps, until no point moves by more than 1e-9 px).

    Parameters
    ----------
    lin : Linearisation
        The forward map (distorted -> linearised).
    uv : array_like, shape (..., 2)
        Linearised pixel coordinates.

    Returns
    -------
    ndarray, shape (..., 2)
        Distorted pixel coordinates ``p`` with ``apply_linearisation(lin, p) == uv``.

    Raises
    ------
    KisscalError
        When the iteration does not converge (a point far outside the fitted area, where
        the polynomial may fold over).
    """
    target = _as_points(uv)
    p = target.copy()
    # Start from the point moved back by the correction there: within 0.1 px of the
    # answer for lens distortion, so Newton converges in two or three steps.
    p = p - (apply_linearisation(lin, p) - target)
    for _ in range(30):
        r = apply_linearisation(lin, p) - target
        jac = _jacobian(lin, p)
        det = jac[..., 0, 0] * jac[..., 1, 1] - jac[..., 0, 1] * jac[..., 1, 0]
        det = np.where(np.abs(det) < 1e-12, np.nan, det)
        du = (jac[..., 1, 1] * r[..., 0] - jac[..., 0, 1] * r[..., 1]) / det
        dv = (jac[..., 0, 0] * r[..., 1] - jac[..., 1, 0] * r[..., 0]) / det
        p[..., 0] -= du
        p[..., 1] -= dv
        step = np.hypot(du, dv)
        if not np.all(np.isfinite(step)):
            break
        if step.size == 0 or step.max() < 1e-9:
            return p
    raise EstimationFailed(
        "inverse linearisation did not converge: a point lies far outside the linearised area"
    )


def anchor_affine(lin: Linearisation, centre_px: ArrayLike) -> NDArray[np.float64]:
    """The affine map ``A`` (3 x 3) that makes ``A ∘ lin`` the identity to first order at
    ``centre_px``: ``A(y) = c + J⁻¹ (y - P(c))`` with ``P(c)`` and ``J`` the value and
    Jacobian of the polynomial there."""
    c = np.asarray(centre_px, dtype=float).reshape(1, 2)
    pc = apply_linearisation(lin, c)[0]
    jinv = np.linalg.inv(_jacobian(lin, c)[0])
    a = np.eye(3)
    a[:2, :2] = jinv
    a[:2, 2] = c[0] - jinv @ pc
    return a


def compose_affine(a: ArrayLike, lin: Linearisation) -> Linearisation:
    """``A ∘ lin``: an affine map of a 15-term polynomial is again one (same 30 numbers)."""
    a = np.asarray(a, dtype=float)
    coef = a[:2, :2] @ np.vstack([lin.x, lin.y])
    coef[:, 0] += a[:2, 2]
    return Linearisation(lin.center_px, lin.scale_px, coef[0], coef[1], lin.quality)


def fit_polynomial(
    distorted_uv: ArrayLike,
    target_uv: ArrayLike,
    center_px: tuple[float, float],
    scale_px: float,
    weights: ArrayLike | None = None,
) -> Linearisation:
    """Least-squares 15 + 15 coefficients mapping distorted points onto target points.

    Solves Küçük 2005, eqs. 2.3 and 2.4 (``Z x = u''``, ``Z y = v''``) on normalised
    coordinates, by SVD least squares on the column-equilibrated term matrix: no normal
    equations, so the condition number enters once, not squared.

    Parameters
    ----------
    distorted_uv : array_like, shape (N, 2)
        Measured (distorted) dot positions, px.
    target_uv : array_like, shape (N, 2)
        Their optimal-grid positions, px.
    center_px, scale_px
        Normalisation (see :class:`Linearisation`).
    weights : array_like, shape (N,), optional
        Relative weight of each point's squared residual (default: all equal).

    Returns
    -------
    Linearisation
        Coefficients without quality figures.
    """
    d = _as_points(distorted_uv, "distorted_uv").reshape(-1, 2)
    t = _as_points(target_uv, "target_uv").reshape(-1, 2)
    if d.shape != t.shape:
        raise InputError(f"distorted and target points differ in shape: {d.shape} vs {t.shape}")
    if len(d) < N_TERMS:
        raise EstimationFailed(f"a 4th-order linearisation needs at least 15 dots, got {len(d)}")
    z = poly_terms((d[:, 0] - center_px[0]) / scale_px, (d[:, 1] - center_px[1]) / scale_px)
    if weights is not None:
        root = np.sqrt(np.asarray(weights, dtype=float).reshape(-1, 1))
        z, t = z * root, t * root
    norms = np.linalg.norm(z, axis=0)
    norms[norms == 0] = 1.0
    coef, _, rank, _ = np.linalg.lstsq(z / norms, t, rcond=None)
    if rank < N_TERMS:
        raise EstimationFailed(
            "grid dots do not span the image in two directions: cannot fit 15 terms per axis"
        )
    coef = coef / norms[:, None]
    return Linearisation(center_px, scale_px, coef[:, 0], coef[:, 1])
