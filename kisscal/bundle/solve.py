"""Sparse Levenberg-Marquardt with the Schur complement (Hartley & Zisserman, A6.3).

The normal equations of a wand adjustment have the block form
``[[U, W], [W^T, V]] [dc; dw] = -[gc; gw]``: ``U`` couples each camera's unknowns with
themselves only, ``V`` each field's five wand unknowns with themselves only, and ``W``
a camera with a field it saw. Eliminating the wand unknowns leaves the reduced camera
system ``(U - W V^-1 W^T) dc = -gc + W V^-1 gw`` of a few hundred unknowns, solved
densely; the wand increments follow field by field. Every block is built with array
operations over all observations (segment sums over observations sorted by field and
camera), never a loop over fields. Marquardt's damping ``lambda diag(H)`` makes the
step invariant to the units of the unknowns (the role ``x_scale="jac"`` plays in
:func:`scipy.optimize.least_squares`), and a robust loss enters as iteratively
re-weighted least squares (Triggs et al. 2000, section 3.2).

References
----------
Hartley, R., & Zisserman, A. (2004). Multiple View Geometry in Computer Vision, 2nd ed.,
appendix A6.3.
Triggs, B., McLauchlan, P. F., Hartley, R. I., & Fitzgibbon, A. W. (2000). Bundle
adjustment - a modern synthesis. LNCS 1883.
Marquardt, D. W. (1963). An algorithm for least-squares estimation of nonlinear
parameters. J. SIAM 11(2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import solve_triangular

from kisscal.bundle.model import (
    N_CAMERA,
    N_WAND,
    State,
    project,
    wand_jacobian,
    wand_points,
)


@dataclass(frozen=True)
class Problem:
    """Observations of an adjustment, sorted by field then camera, with their structure.

    Attributes
    ----------
    field, camera : ndarray of int, shape (n,)
    offsets : ndarray, shape (n,)
        Each row's marker offset along the wand (mm).
    uv_px : ndarray, shape (n, 2)
    control_camera : ndarray of int, shape (m,)
    control_xyz_mm, control_uv_px : ndarray, shapes (m, 3), (m, 2)
    n_cameras, n_fields : int
    control_weight : float
        Weight of a control observation's squared residual against a wand observation's
        (the inverse ratio of their noise variances).
    weight : ndarray, shape (n,), optional
        Weight of each wand observation's squared residual (None: 1 each).
    """

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    offsets: NDArray[np.float64]
    uv_px: NDArray[np.float64]
    control_camera: NDArray[np.int64]
    control_xyz_mm: NDArray[np.float64]
    control_uv_px: NDArray[np.float64]
    n_cameras: int
    n_fields: int
    control_weight: float = 1.0
    weight: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class Loss:
    """A robust loss ``rho`` of the squared residual norm over ``scale_px`` squared."""

    kind: str
    scale_px: float

    def rho(self, z: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``rho(z)`` and ``rho'(z)`` (scipy's definitions of the losses)."""
        if self.kind == "soft_l1":
            root = np.sqrt(1.0 + z)
            return 2.0 * (root - 1.0), 1.0 / root
        if self.kind == "huber":
            big = z > 1.0
            root = np.sqrt(np.where(big, z, 1.0))
            return np.where(big, 2.0 * root - 1.0, z), np.where(big, 1.0 / root, 1.0)
        if self.kind == "cauchy":
            return np.log1p(z), 1.0 / (1.0 + z)
        return z, np.ones_like(z)

    def cost(self, r: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
        """Half the summed loss of residual rows ``r (n, 2)`` and each row's IRLS weight."""
        s2 = self.scale_px**2
        value, weight = self.rho(np.sum(r * r, axis=1) / s2)
        return 0.5 * s2 * float(np.sum(value)), weight


class _Blocks:
    """Segment structure of the sorted observations: pairs (camera, field) and fields."""

    def __init__(self, p: Problem) -> None:
        key = p.field * p.n_cameras + p.camera
        change = np.flatnonzero(np.diff(key)) + 1
        self.pair_start = np.r_[0, change]
        self.pair_field = p.field[self.pair_start]
        self.pair_camera = p.camera[self.pair_start]
        fchange = np.flatnonzero(np.diff(p.field)) + 1
        self.field_start = np.r_[0, fchange]
        pchange = np.flatnonzero(np.diff(self.pair_field)) + 1
        self.field_pair_start = np.r_[0, pchange]
        self.n_fields = p.n_fields
        # one observation per pair (every free point, a wand's markers apart): a segment
        # sum over pairs would copy its rows, the same numbers
        self.one_per_pair = len(self.pair_start) == len(key)
        self._grid: NDArray[np.float64] | None = None

    def pair_sum(self, rows: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rows (one per observation) summed over each pair."""
        return rows if self.one_per_pair else np.add.reduceat(rows, self.pair_start)

    def grid(self, n_cameras: int) -> NDArray[np.float64]:
        """The (2, camera, field, 5, 16) grid :func:`_field_products` fills: allocated and
        zeroed once per problem, as every step writes the same pairs' blocks (a fresh 10 MB
        for 1200 points and 6 cameras cost each step as much as the product itself)."""
        if self._grid is None:
            self._grid = np.zeros((2, n_cameras, self.n_fields, N_WAND, N_CAMERA))
        return self._grid


def evaluate(
    problem: Problem, state: State, jacobian: bool
) -> tuple[NDArray, NDArray | None, NDArray | None, NDArray, NDArray | None]:
    """Residuals (projected - observed) and Jacobians of wand and control observations."""
    xyz = wand_points(state, problem.field, problem.offsets)
    uv, jc, jp = project(state, problem.camera, xyz, jacobian)
    jw = wand_jacobian(state, problem.field, problem.offsets, jp) if jacobian else None
    cuv, cjc, _ = project(state, problem.control_camera, problem.control_xyz_mm, jacobian)
    root = np.sqrt(problem.control_weight)  # weighted rows: the loss sees sqrt(w) r
    cjc = cjc * root if cjc is not None else None
    r = uv - problem.uv_px
    if problem.weight is not None:
        rows = np.sqrt(problem.weight)[:, None]
        r = r * rows
        jc = jc * rows[:, :, None] if jc is not None else None
        jw = jw * rows[:, :, None] if jw is not None else None
    return r, jc, jw, root * (cuv - problem.control_uv_px), cjc


def _normal_equations(problem: Problem, blocks: _Blocks, state: State, loss: Loss):
    r, jc, jw, cr, cjc = evaluate(problem, state, jacobian=True)
    _, w = loss.cost(r)
    _, cw = loss.cost(cr)
    wjc = jc * w[:, None, None]
    U = np.zeros((problem.n_cameras, N_CAMERA, N_CAMERA))
    g_cam = np.zeros((problem.n_cameras, N_CAMERA))
    for rows, J, WJ, res in (
        (problem.camera, jc, wjc, r),
        (problem.control_camera, cjc, cjc * cw[:, None, None], cr),
    ):
        for c in range(problem.n_cameras):
            sel = rows == c
            if sel.any():
                a = J[sel].reshape(-1, N_CAMERA)
                b = WJ[sel].reshape(-1, N_CAMERA)
                U[c] += b.T @ a
                g_cam[c] += b.T @ res[sel].ravel()
    # batched products of 2-row blocks by matmul: einsum took three to five times longer
    wjw_t = (jw * w[:, None, None]).transpose(0, 2, 1)
    V = np.add.reduceat(wjw_t @ jw, blocks.field_start)
    g_wand = np.add.reduceat(np.einsum("nik,nk->ni", wjw_t, r), blocks.field_start)
    W = blocks.pair_sum(wjc.transpose(0, 2, 1) @ jw)
    return U, V, W, g_cam, g_wand


def _field_products(
    blocks: _Blocks, Y: NDArray[np.float64], W: NDArray[np.float64], n_cameras: int
) -> NDArray[np.float64]:
    """``W V^-1 W^T``: the sum over fields of ``Y_a W_b^T`` for every two cameras ``a, b``
    that saw the field (rows and columns camera-major).

    Each pair's block is placed in a (camera, field) grid with zeros where the camera did
    not see the field, so the fields and wand unknowns form the inner dimension of one
    product per two cameras, summed by BLAS: a segment sum over every two pairs of each
    field cost ten to twenty times more. Batched per two cameras, each product stays
    below the size at which OpenBLAS spreads it over threads, which on a busy machine
    spin longer than they compute. The product is symmetric (``V`` is): the blocks above
    the diagonal are computed, and mirrored below it.
    """
    C = n_cameras
    dense = blocks.grid(C)
    # each pair's block is written whole (a camera's 16 unknowns last): written with the
    # field between them, the scattered writes cost as much as the products
    dense[0, blocks.pair_camera, blocks.pair_field] = Y.transpose(0, 2, 1)
    dense[1, blocks.pair_camera, blocks.pair_field] = W.transpose(0, 2, 1)
    left, right = dense.reshape(2, C, -1, N_CAMERA)
    products = np.empty((C, C, N_CAMERA, N_CAMERA))
    for a in range(C):
        products[a, a:] = left[a].T @ right[a:]
    upper = np.triu_indices(C, 1)
    products[upper[::-1]] = products[upper].transpose(0, 2, 1)
    return products.transpose(0, 2, 1, 3).reshape(C * N_CAMERA, C * N_CAMERA)


def _reduced_system(
    problem: Problem, blocks: _Blocks, normal: tuple, lam: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The damped reduced camera system ``S``, the wand blocks' inverses and ``W V^-1``."""
    U, V, W = normal[:3]
    C = problem.n_cameras
    diag = np.einsum("fii->fi", V)
    # a one-marker wand (a free point) has no direction: its two rows are zero, held
    Vd = V + (lam * diag + (diag == 0.0))[:, :, None] * np.eye(N_WAND)
    Vinv = np.linalg.inv(Vd)
    Y = W @ Vinv[blocks.pair_field]  # (P, 16, 5)
    S = np.zeros((C, N_CAMERA, C, N_CAMERA))
    S[np.arange(C), :, np.arange(C)] = U + lam * np.einsum("cii->ci", U)[:, :, None] * np.eye(
        N_CAMERA
    )
    return S.reshape(C * N_CAMERA, C * N_CAMERA) - _field_products(blocks, Y, W, C), Vinv, Y


def _damped_step(
    problem: Problem, blocks: _Blocks, normal: tuple, lam: float, free: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    _, _, W, g_cam, g_wand = normal
    C = problem.n_cameras
    S, Vinv, Y = _reduced_system(problem, blocks, normal, lam)
    rhs = -g_cam.copy()
    np.add.at(rhs, blocks.pair_camera, np.einsum("pij,pj->pi", Y, g_wand[blocks.pair_field]))
    idx = np.flatnonzero(free.ravel())
    sub = S[np.ix_(idx, idx)]
    scale = 1.0 / np.sqrt(np.maximum(np.diag(sub), 1e-300))
    x = _spd_solve(sub * scale[:, None] * scale[None, :], rhs.ravel()[idx] * scale)
    d_cam = np.zeros(C * N_CAMERA)
    d_cam[idx] = x * scale
    d_cam = d_cam.reshape(C, N_CAMERA)
    back = np.einsum("pji,pj->pi", W, d_cam[blocks.pair_camera])  # W^T dc per pair
    back_f = np.add.reduceat(back, blocks.field_pair_start)
    d_wand = np.einsum("fij,fj->fi", Vinv, -g_wand - back_f)
    return d_cam, d_wand


def _spd_solve(A: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``A^-1 b`` for the damped reduced camera system, symmetric positive definite: by
    Cholesky's factor and two triangular solves (Triggs et al. 2000), which
    cost a tenth to a hundredth of LAPACK's general LU solve on a busy machine (OpenBLAS
    threads spinning on a 100-unknown system); by LU when rounding left it indefinite."""
    try:
        L = np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        return np.linalg.solve(A, b)
    return solve_triangular(L.T, solve_triangular(L, b, lower=True), lower=False)


def levenberg_marquardt(
    problem: Problem,
    state: State,
    free: NDArray[np.bool_],
    loss: Loss,
    tolerance: float,
    max_iterations: int,
) -> tuple[State, int, str]:
    """Minimise the robust reprojection cost from ``state``.

    Parameters
    ----------
    problem : Problem
        Observations sorted by field, then camera; every field in ``0..n_fields-1`` seen.
    state : State
        Starting cameras and wand poses.
    free : ndarray of bool, shape (C, 16)
        Camera unknowns that move (the others stay at their values in ``state``).
    loss : Loss
    tolerance : float
        Stop when an accepted step lowers the cost by less than this fraction.
    max_iterations : int

    Returns
    -------
    state : State
    iterations : int
    message : str
    """
    blocks = _Blocks(problem)
    r, _, _, cr, _ = evaluate(problem, state, jacobian=False)
    cost = loss.cost(r)[0] + loss.cost(cr)[0]
    lam = 1e-3
    for iteration in range(1, max_iterations + 1):
        normal = _normal_equations(problem, blocks, state, loss)
        while True:
            d_cam, d_wand = _damped_step(problem, blocks, normal, lam, free)
            trial = state.moved(d_cam, d_wand)
            r, _, _, cr, _ = evaluate(problem, trial, jacobian=False)
            new_cost = loss.cost(r)[0] + loss.cost(cr)[0]
            if np.isfinite(new_cost) and new_cost <= cost:
                break
            lam *= 10.0
            if lam > 1e12:
                return state, iteration, "no step lowers the cost further"
        lam = max(lam / 10.0, 1e-12)
        gain = cost - new_cost
        state, cost = trial, new_cost
        if gain <= tolerance * cost:
            return state, iteration, "the cost stopped decreasing"
    return state, max_iterations, "iteration limit reached"


def control_share(
    problem: Problem, state: State, free: NDArray[np.bool_], loss: Loss
) -> NDArray[np.float64]:
    """The unknowns' share the control observations determine, ``tr(N^-1 N_c)``, per
    camera (the trace over that camera's unknowns; their sum is the whole share).

    ``N`` is the normal matrix at ``state`` (robust weights included, no damping) and
    ``N_c`` the control observations' part of it; the control observations' redundancy
    is their count less this share (Förstner 1979), the rest of the unknowns are the
    wand's. The control points are fixed, so ``N_c`` holds camera unknowns only and the
    trace needs only the cameras' block of ``N^-1``, the reduced camera system's inverse.
    """
    blocks = _Blocks(problem)
    normal = _normal_equations(problem, blocks, state, loss)
    S = _reduced_system(problem, blocks, normal, 0.0)[0]
    _, _, _, cr, cjc = evaluate(problem, state, jacobian=True)
    C = problem.n_cameras
    if cjc is None or not len(cr):
        return np.zeros(C)
    cw = loss.cost(cr)[1]
    Nc = np.zeros((C, N_CAMERA, C, N_CAMERA))
    for c in range(C):
        sel = problem.control_camera == c
        a = cjc[sel].reshape(-1, N_CAMERA)
        b = (cjc[sel] * cw[sel, None, None]).reshape(-1, N_CAMERA)
        Nc[c, :, c] = b.T @ a
    idx = np.flatnonzero(free.ravel())
    Nc = Nc.reshape(C * N_CAMERA, C * N_CAMERA)[np.ix_(idx, idx)]
    diag = np.einsum("ii->i", np.linalg.solve(S[np.ix_(idx, idx)], Nc))
    return np.bincount(idx // N_CAMERA, diag, C)
