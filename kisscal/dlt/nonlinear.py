"""Iterative DLT solvers: the modified DLT (MDLT) and refinement in pixels, with lens terms.

MDLT (Kolahi et al. 2007, section 4, eqs. 10-14): the 11 DLT parameters have only 10
degrees of freedom for a real camera; Hatze's constraint (eq. 10) ties them together.
Kolahi enforces it by eliminating L1 and iterating linearised least squares; eliminating
L1 divides by its coefficient in eq. 10, ``L9 (L5 L9 + L6 L10 + L7 L11) - L5 (L9^2 + L10^2 +
L11^2)``, which is zero when ``L5 = L9 = 0``: a level camera looking along the lab Y axis
(an ordinary gait-lab camera). kisscal instead parametrises
the camera so that the constraint holds identically: the constraint is equivalent to a
zero skew (see :func:`kisscal.dlt.camera.hatze_violation`), so the DLT matrix is built as
``K R0 exp([w]x) [I | -C]`` with ``K = [[fu, 0, u0], [0, fv, v0], [0, 0, 1]]``, the
rotation an increment ``w`` on the starting rotation ``R0`` (never near a singularity of
the rotation vector) and ``C`` the centre. The same algebraic residual as the linear DLT
is then minimised by Gauss-Newton/Levenberg-Marquardt to convergence.

Refinement (Woltring & Huiskes 1990, bias of the linear estimator and iterative
adjustment): the linear DLT minimises an algebraic error, biased when image coordinates
are noisy; refinement minimises the reprojection error in pixels (optionally under the
zero-skew constraint, optionally with Kolahi's lens terms L12..L16, eqs. 2-3).

Both work on the Hartley-normalised coordinates of :mod:`kisscal.dlt.linear` (similarity
transforms keep rotations orthogonal and skew zero) and convert back to L1..L11.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.optimize
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from kisscal._shared import similarity_normaliser
from kisscal.dlt.camera import decompose_matrix
from kisscal.dlt.lens import distort_xy
from kisscal.dlt.linear import check_control_points, solve_dlt
from kisscal.dlt.model import dlt_to_matrix, matrix_to_dlt
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams
from kisscal.errors import EstimationFailed

N_LENS = 5


def lens_frame(P: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Where and in what shape the lens terms of a 3 x 4 projection matrix act.

    Returns the principal point ``(u0, v0)`` (px) and ``A = K2 / fu``, the upper 2 x 2 of
    ``K`` scaled to ``A[0, 0] = 1`` (``[[1, skew / fu], [0, fv / fu]]``): a pixel offset
    ``d`` from the principal point is ``A q`` with ``q`` the offset in square, unskewed
    pixels of the width of ``u``'s. Read from ``K K^T = M M^T / |m3|^2`` (``M`` the
    left 3 x 3 of ``P``, ``m3`` its last row), so it needs no decomposition and does
    not depend on the scale or sign of ``P``. A matrix that is no camera (``K2 K2^T`` not
    positive definite: a linear DLT of too flat or too few points) gives NaN, which the
    refinement reports as a start it cannot take.
    """
    centre, A = lens_frames(np.asarray(P, dtype=float)[None])
    return centre[0], A[0]


def lens_frames(P: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`lens_frame` of a stack of matrices (..., 3, 4): centres (..., 2) and
    shapes (..., 2, 2), each matrix's numbers whatever the stack (sums written out)."""
    M = P[..., :3]
    c = M[..., 2, :]
    cc = _dot(c, c)
    centre = np.stack([_dot(M[..., 0, :], c), _dot(M[..., 1, :], c)], axis=-1) / cc[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        # K2 K2^T = M2 M2^T / cc - centre centre^T
        g00 = _dot(M[..., 0, :], M[..., 0, :]) / cc - centre[..., 0] * centre[..., 0]
        g01 = _dot(M[..., 0, :], M[..., 1, :]) / cc - centre[..., 0] * centre[..., 1]
        g11 = _dot(M[..., 1, :], M[..., 1, :]) / cc - centre[..., 1] * centre[..., 1]
        fv = np.sqrt(g11)
        skew = g01 / fv
        fu = np.sqrt(g00 - skew**2)
        A = np.zeros((*cc.shape, 2, 2))
        A[..., 0, 0] = 1.0
        A[..., 0, 1] = skew / fu
        A[..., 1, 1] = fv / fu
    return centre, A


def _product(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Matrix product ``a @ b`` of (stacks of) matrices with :func:`_dot`'s sums."""
    return _dot(a[..., :, None, :], np.swapaxes(b, -1, -2)[..., None, :, :])


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum of products over the last axis, term by term in order: the same rounding for
    one row as for a stack of them (a BLAS product may not promise that)."""
    out = a[..., 0] * b[..., 0]
    for k in range(1, a.shape[-1]):
        out = out + a[..., k] * b[..., k]
    return out


def lens_offsets(
    uv: NDArray[np.float64],
    frame: tuple[NDArray[np.float64], NDArray[np.float64]],
    lens: ArrayLike,
) -> NDArray[np.float64]:
    """Kolahi et al. 2007 eqs. 2-3: image corrections ``(du, dv)`` for L12..L16.

    ``frame`` is :func:`lens_frame`'s ``(centre, A)``. The terms act on the offset from
    the principal point in square pixels, ``(xi, eta) = A^-1 (u - u0, v - v0)``, with
    ``r^2 = xi^2 + eta^2``:
    ``dxi = xi (L12 r^2 + L13 r^4 + L14 r^6) + L15 (r^2 + 2 xi^2) + L16 xi eta``,
    ``deta = eta (L12 r^2 + L13 r^4 + L14 r^6) + L16 (r^2 + 2 eta^2) + L15 xi eta``
    (Kolahi's eq. 2), and ``(du, dv) = A (dxi, deta)``. For square pixels without skew
    (``A = I``) this is the paper's pixel form; with a pixel aspect (the KISS cameras'
    pixels are nearly twice as tall as wide) the terms stay radial about the optical
    axis, as a lens is, and as Brown's model (and OpenCV's) is in normalised coordinates.
    Corrected coordinates are ``uv + offsets``. The terms are Brown's (L15 is OpenCV's
    ``p2``, L16 its ``p1``), in the DLT literature's form (:func:`kisscal.dlt.lens.distort`).
    """
    centre, A = frame
    return _offsets(uv - centre, A[0, 1], A[1, 1], np.asarray(lens, dtype=float))


def _lens_offsets_rows(
    u: NDArray[np.float64],
    frames: tuple[NDArray[np.float64], NDArray[np.float64]],
    lenses: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`lens_offsets` of the same points ``u`` (N, 2) under each of several frames
    (:func:`lens_frames` of a stack) and lenses (rows of ``lenses``), shape (H, N, 2):
    the same element-wise operations on the same numbers, every row at once (the
    columns of a forward-difference Jacobian)."""
    centre, A = frames
    return _offsets(u - centre[:, None, :], A[:, 0, 1, None], A[:, 1, 1, None], lenses[:, None])


def _offsets(
    d: NDArray[np.float64],
    a01: float | NDArray[np.float64],
    a11: float | NDArray[np.float64],
    lens: NDArray[np.float64],
) -> NDArray[np.float64]:
    """The arithmetic of :func:`lens_offsets` on offsets ``d`` (..., 2) from the principal
    point, ``A``'s two free entries and L12..L16 (shape (5,), or (..., 1, 5): a lens per
    row of ``d``)."""
    eta = d[..., 1] / a11
    xi = d[..., 0] - a01 * eta
    brown = lens[..., [0, 1, 4, 3, 2]]  # L12 L13 L14 L15 L16 in OpenCV's order k1 k2 p1 p2 k3
    dxi, deta = distort_xy(brown, xi, eta, dlt_form=True)
    return np.stack([dxi + a01 * deta, a11 * deta], axis=-1)


def correct_lens(L: ArrayLike, lens: ArrayLike | None, uv_px: ArrayLike) -> NDArray[np.float64]:
    """Apply Kolahi's lens correction (eq. 1): pixel coordinates the 11 DLT terms map to.

    The projection point ``(u0, v0)`` of eq. 3 is the principal point of ``L``, and the
    terms act in its square pixels (:func:`lens_offsets`).
    With ``lens`` None the coordinates are returned unchanged.
    """
    uv = np.asarray(uv_px, dtype=float)
    if lens is None:
        return uv
    return uv + lens_offsets(uv, lens_frame(dlt_to_matrix(L)), lens)


class _Problem:
    """Control points on normalised coordinates and a camera parametrisation."""

    def __init__(
        self, xyz: NDArray[np.float64], uv: NDArray[np.float64], L0: NDArray[np.float64]
    ) -> None:
        self.T3 = similarity_normaliser(xyz)
        self.T2 = similarity_normaliser(uv)
        self.X = np.hstack([xyz @ self.T3[:3, :3].T + self.T3[:3, 3], np.ones((len(xyz), 1))])
        self.u = uv @ self.T2[:2, :2].T + self.T2[:2, 2]
        P0n = self.T2 @ dlt_to_matrix(L0) @ np.linalg.inv(self.T3)
        K, self.R0, C = decompose_matrix(P0n)
        self.theta_constrained = np.r_[K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.zeros(3), C]
        self.theta_free = (P0n / P0n[2, 3]).ravel()[:11]

    def matrix(self, theta: NDArray[np.float64], constrained: bool) -> NDArray[np.float64]:
        return self.matrices(np.asarray(theta)[None], constrained)[0]

    def matrices(self, thetas: NDArray[np.float64], constrained: bool) -> NDArray[np.float64]:
        """The normalised 3 x 4 matrix of each row of ``thetas``, shape (H, 3, 4)."""
        if not constrained:
            return np.concatenate([thetas[:, :11], np.ones((len(thetas), 1))], 1).reshape(-1, 3, 4)
        R = _product(self.R0, Rotation.from_rotvec(thetas[:, 4:7]).as_matrix())
        Rt = np.concatenate([R, -_dot(R, thetas[:, None, 7:10])[..., None]], axis=-1)  # [R | -RC]
        fu, fv, u0, v0 = thetas[:, :4, None].transpose(1, 0, 2)
        # K [R | -RC], K = [[fu, 0, u0], [0, fv, v0], [0, 0, 1]]
        return np.stack([fu * Rt[:, 0] + u0 * Rt[:, 2], fv * Rt[:, 1] + v0 * Rt[:, 2], Rt[:, 2]], 1)

    def n_camera(self, constrained: bool) -> int:
        return 10 if constrained else 11

    def algebraic(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        P = self.matrix(theta, constrained=True)
        h = self.X @ P.T
        return (h[:, :2] - self.u * h[:, 2:3]).ravel()

    def geometric(
        self, theta: NDArray[np.float64], constrained: bool, lens: bool
    ) -> NDArray[np.float64]:
        return self.geometric_rows(np.asarray(theta)[None], constrained, lens)[0]

    def geometric_rows(
        self, thetas: NDArray[np.float64], constrained: bool, lens: bool
    ) -> NDArray[np.float64]:
        """:meth:`geometric` of each row of ``thetas`` (H, n), every row at once: a row's
        numbers do not depend on the others (sums written out, no BLAS), so the moved
        points of a forward-difference Jacobian get exactly one evaluation's numbers."""
        Ps = self.matrices(thetas, constrained)
        X = self.X[None, :, None, :3]  # (1, N, 1, 3): the homogeneous 1 is P's last column
        h = _dot(X, Ps[:, None, :, :3]) + Ps[:, None, :, 3]  # (H, N, 3)
        proj = h[..., :2] / h[..., 2:3]
        u = np.broadcast_to(self.u, proj.shape)
        if lens:
            terms = self.lens_terms(thetas, constrained)
            u = u + _lens_offsets_rows(self.u, lens_frames(Ps), terms)
        return (u - proj).reshape(len(thetas), -1)

    def lens_terms(self, theta: NDArray[np.float64], constrained: bool) -> NDArray[np.float64]:
        """L12..L16 (normalised) from the estimated first ones, the rest 0; of each row
        of a stack of parameter vectors (..., n) too."""
        est = theta[..., self.n_camera(constrained) :]
        rest = np.zeros((*est.shape[:-1], N_LENS - est.shape[-1]))
        return np.concatenate([est, rest], axis=-1)

    def to_dlt(self, theta: NDArray[np.float64], constrained: bool) -> NDArray[np.float64]:
        P = np.linalg.solve(self.T2, self.matrix(theta, constrained) @ self.T3)
        return matrix_to_dlt(P)

    def lens_to_px(self, lens_n: NDArray[np.float64]) -> NDArray[np.float64]:
        # Normalised pixels are a * pixels + shift; the shift cancels in xi, eta.
        a = self.T2[0, 0]
        return lens_n * np.array([a**2, a**4, a**6, a, a])


def _forward_jacobian(fun, rows) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The Jacobian of ``fun`` by forward differences, value for value scipy's
    (``least_squares``' default ``jac="2-point"``: step ``sqrt(eps) max(1, |x|)`` of
    ``x``'s sign, the step taken as ``(x + h) - x``), the moved points' residuals from
    ``rows`` (a row of residuals per row of parameters) in one call: the refinement's
    Jacobian costs a few residual evaluations instead of one per parameter."""
    rel = np.finfo(np.float64).eps ** 0.5

    def jacobian(x: NDArray[np.float64]) -> NDArray[np.float64]:
        f0 = fun(x)
        h = rel * ((x >= 0).astype(float) * 2 - 1) * np.maximum(1.0, np.abs(x))
        moved = np.tile(x, (x.size, 1))
        moved[np.diag_indices(x.size)] = x + h
        dx = (x + h) - x
        return ((rows(moved) - f0) / dx[:, None]).T

    return jacobian


def _solve(fun, theta0: NDArray[np.float64], params: DltParams, camera: str, jac: Any = "2-point"):
    if not np.isfinite(fun(theta0)).all():
        raise EstimationFailed(
            f"camera {camera}: the DLT iteration cannot start (non-finite residuals at the "
            "linear solution: a control point on the camera's focal plane, or a linear DLT "
            "that is no camera, from control points too flat or too few)"
        )
    result = scipy.optimize.least_squares(
        fun,
        theta0,
        method="lm",
        xtol=params.tolerance,
        ftol=params.tolerance,
        gtol=params.tolerance,
        max_nfev=params.max_iterations,
        jac=jac,
    )
    if result.status <= 0 or not np.isfinite(result.x).all():
        raise EstimationFailed(
            f"camera {camera}: the DLT iteration did not converge ({result.message})"
        )
    return result


def solve_mdlt(
    xyz_mm: ArrayLike,
    uv_px: ArrayLike,
    params: DltParams = DEFAULT_PARAMS,
    camera: str = "",
    L0: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], int]:
    """Modified DLT: linear-DLT residuals under Hatze's constraint (Kolahi et al. 2007, eq. 10).

    Parameters
    ----------
    xyz_mm, uv_px : array_like, shapes (N, 3) and (N, 2)
        Control points (lab mm) and their linearised pixel coordinates.
    params : DltParams
        Tolerances and iteration cap.
    camera : str
        Camera id for messages.
    L0 : array_like, shape (11,), optional
        Starting DLT (default: the linear DLT of the same points, Kolahi's step 1).

    Returns
    -------
    L : ndarray, shape (11,)
        DLT parameters satisfying the constraint to rounding error (zero-skew camera).
    n_evaluations : int
        Residual evaluations used.
    """
    xyz, uv = check_control_points(xyz_mm, uv_px, params, camera)
    L0 = solve_dlt(xyz, uv, params, camera) if L0 is None else np.asarray(L0, dtype=float)
    prob = _Problem(xyz, uv, L0)
    res = _solve(prob.algebraic, prob.theta_constrained, params, camera)
    return prob.to_dlt(res.x, constrained=True), int(res.nfev)


def refine_dlt(
    xyz_mm: ArrayLike,
    uv_px: ArrayLike,
    L0: ArrayLike,
    params: DltParams = DEFAULT_PARAMS,
    camera: str = "",
    weights: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, int]:
    """Minimise the (weighted) reprojection error in pixels, started from ``L0``
    (iterative adjustment).

    Parameters
    ----------
    xyz_mm, uv_px : array_like, shapes (N, 3) and (N, 2)
        Control points and their pixel coordinates.
    L0 : array_like, shape (11,)
        Starting DLT parameters (linear DLT or MDLT).
    params : DltParams
        ``mdlt`` keeps Hatze's constraint (zero-skew parametrisation, 10 unknowns);
        ``lens`` adds Kolahi's L12..L16; tolerances and iteration cap.
    camera : str
        Camera id for messages.
    weights : array_like, shape (N,), optional
        Each point's weight (the inverse of its image variance, in any common unit):
        points from sources of different noise in one fit. Default: all equal.

    Returns
    -------
    L : ndarray, shape (11,)
    lens : ndarray, shape (5,) or None
        L12..L16 in pixel units (Kolahi eq. 2) when ``params.lens``; beyond the first
        ``params.lens_terms`` they are 0.
    n_evaluations : int
    """
    xyz, uv = check_control_points(xyz_mm, uv_px, params, camera)
    if params.lens and len(xyz) < 11:
        raise EstimationFailed(
            f"camera {camera}: the {11 + params.lens_terms}-parameter DLT needs at least 11 "
            f"control points, got {len(xyz)}"
        )
    prob = _Problem(xyz, uv, np.asarray(L0, dtype=float))
    constrained = params.mdlt
    theta0 = prob.theta_constrained if constrained else prob.theta_free
    if params.lens:
        theta0 = np.r_[theta0, np.zeros(params.lens_terms)]
    scale = 1.0 if weights is None else np.repeat(np.sqrt(np.asarray(weights, dtype=float)), 2)

    def residuals(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return scale * prob.geometric(theta, constrained, params.lens)

    def rows(thetas: NDArray[np.float64]) -> NDArray[np.float64]:
        return scale * prob.geometric_rows(thetas, constrained, params.lens)

    res = _solve(residuals, theta0, params, camera, _forward_jacobian(residuals, rows))
    lens = prob.lens_to_px(prob.lens_terms(res.x, constrained)) if params.lens else None
    return prob.to_dlt(res.x, constrained), lens, int(res.nfev)
