"""Bundle adjustment of cameras, lenses and wand poses (Triggs et al. 2000).

The unknowns, the rigid wand (its marker spacing a hard constraint: Theriault et al.
2014's wand-length term made exact), the robust cost and the outlier passes are those of
docs/methods.md, "Wand calibration". Control points (the rods' surveyed markers, held
fixed) fix the lab frame and scale; without them one camera's pose is held. The solver is
:mod:`kisscal.bundle.solve`'s, or :func:`scipy.optimize.least_squares` (``solver``).

References
----------
Triggs, B., McLauchlan, P. F., Hartley, R. I., & Fitzgibbon, A. W. (2000). Bundle
adjustment - a modern synthesis. Vision Algorithms: Theory and Practice, LNCS 1883.
Theriault, D. H., Fuller, N. W., Jackson, B. E., et al. (2014). A protocol and calibration
method for accurate multi-camera field videography. J. Exp. Biol. 217.
Förstner, W. (1979). Ein Verfahren zur Schätzung von Varianz- und Kovarianzkomponenten.
Allgemeine Vermessungs-Nachrichten 86, 446-453.
Koch, K.-R. (1999). Parameter Estimation and Hypothesis Testing in Linear Models, 2nd ed.
Springer.

Examples
--------
>>> import numpy as np
>>> from kisscal.camera import Camera
>>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
>>> R = [np.eye(3), np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])]
>>> cams = tuple(Camera(K, r, np.array([0.0, 0, 3000]), np.zeros(5)) for r in R)
>>> rng = np.random.default_rng(0)
>>> poses = WandPoses(rng.uniform(-300, 300, (30, 3)), rng.normal(size=(30, 3)))
>>> poses = WandPoses(poses.centre_mm, poses.direction / np.linalg.norm(poses.direction,
...                   axis=1, keepdims=True))
>>> xyz = poses.markers_mm([-250.0, 250.0]).reshape(-1, 3)
>>> f, m = np.divmod(np.arange(60), 2)
>>> obs = WandObservations(np.r_[f, f], np.repeat([0, 1], 60), np.r_[m, m],
...     np.concatenate([c.project(xyz) for c in cams]))
>>> start = WandPoses(poses.centre_mm + 5.0, poses.direction)
>>> fit = adjust_bundle(cams, obs, [0.0, 500.0], start, fixed_pose=0,
...     params=BundleParams(lens_terms=()))
>>> bool(np.abs(fit.residuals_px).max() < 1e-6)
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.sparse
from numpy.typing import ArrayLike, NDArray

from kisscal.bundle.model import N_CAMERA, N_WAND, State, project, wand_points
from kisscal.bundle.params import DEFAULT_PARAMS, BundleParams
from kisscal.bundle.solve import Loss, Problem, control_share, levenberg_marquardt
from kisscal.camera import LENS_TERMS, Camera
from kisscal.errors import EstimationFailed


@dataclass(frozen=True)
class WandObservations:
    """Wand marker images, one row per (field, camera, marker), long format.

    Attributes
    ----------
    field : ndarray of int, shape (n,)
        Field index (into the rows of :class:`WandPoses`).
    camera : ndarray of int, shape (n,)
        Camera index.
    marker : ndarray of int, shape (n,)
        Index into the wand's ``markers_mm``.
    uv_px : ndarray, shape (n, 2)
        Image coordinates (linearised by the grid when there is one, else raw).
    weight : ndarray, shape (n,), optional
        Weight of each row's squared residual (the inverse of its kind's noise variance
        relative to the others'; None: 1 each).
    """

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    marker: NDArray[np.int64]
    uv_px: NDArray[np.float64]
    weight: NDArray[np.float64] | None = None

    def __len__(self) -> int:
        return len(self.field)

    def subset(self, keep: ArrayLike) -> WandObservations:
        """The rows selected by a boolean mask or index array."""
        k = np.asarray(keep)
        w = None if self.weight is None else self.weight[k]
        return WandObservations(self.field[k], self.camera[k], self.marker[k], self.uv_px[k], w)

    def weighted(self, weight: NDArray[np.float64] | None) -> WandObservations:
        """The same rows with another ``weight``."""
        return WandObservations(self.field, self.camera, self.marker, self.uv_px, weight)


@dataclass(frozen=True)
class ControlPoints:
    """Observations of points of known lab position (rod markers), long format.

    Attributes
    ----------
    camera : ndarray of int, shape (m,)
    xyz_mm : ndarray, shape (m, 3)
    uv_px : ndarray, shape (m, 2)
    group : ndarray of int, shape (m,)
        Which object each point belongs to (its rod), for leave-one-out checks.
    weight : float
        Weight of each control observation's squared residual against a wand
        observation's: their noise variances' inverse ratio (rod centroids averaged over
        frames are more precise than a moving wand's).
    """

    camera: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    uv_px: NDArray[np.float64]
    group: NDArray[np.int64]
    weight: float = 1.0

    def __len__(self) -> int:
        return len(self.camera)

    def subset(self, keep: ArrayLike) -> ControlPoints:
        """The rows selected by a boolean mask or index array."""
        k = np.asarray(keep)
        return ControlPoints(
            self.camera[k], self.xyz_mm[k], self.uv_px[k], self.group[k], self.weight
        )

    def weighted(self, weight: float) -> ControlPoints:
        """The same points with another ``weight``."""
        return ControlPoints(self.camera, self.xyz_mm, self.uv_px, self.group, weight)


@dataclass(frozen=True)
class WandPoses:
    """The wand's centre (mm) and unit direction (first towards last marker) per field."""

    centre_mm: NDArray[np.float64]
    direction: NDArray[np.float64]

    def markers_mm(self, offsets_mm: ArrayLike) -> NDArray[np.float64]:
        """Marker positions for offsets from the centre, shape (n_fields, n_markers, 3)."""
        s = np.asarray(offsets_mm, dtype=float)
        return self.centre_mm[:, None, :] + s[None, :, None] * self.direction[:, None, :]


@dataclass(frozen=True)
class BundleResult:
    """The adjusted cameras and wand, with the residuals of every observation.

    Attributes
    ----------
    cameras : tuple of Camera
    wand : WandPoses
    residuals_px : ndarray, shape (n, 2)
        Observed minus projected, per wand observation (outliers included).
    inlier : ndarray of bool, shape (n,)
        Wand observations kept in the final adjustment.
    control_residuals_px : ndarray, shape (m, 2)
        Observed minus projected, per control point.
    iterations : int
        Iterations of the final pass.
    message : str
        Why the final pass stopped.
    """

    cameras: tuple[Camera, ...]
    wand: WandPoses
    residuals_px: NDArray[np.float64]
    inlier: NDArray[np.bool_]
    control_residuals_px: NDArray[np.float64]
    iterations: int
    message: str


def centred_offsets(markers_mm: ArrayLike) -> NDArray[np.float64]:
    """Marker offsets along the wand from its centre (mid-way between the end markers)."""
    s = np.asarray(markers_mm, dtype=float)
    return s - 0.5 * (s.min() + s.max())


def free_unknowns(
    n_cameras: int, params: BundleParams, fixed_pose: int | None
) -> NDArray[np.bool_]:
    """Which of each camera's 16 unknowns the adjustment moves, shape (n_cameras, 16)."""
    free = np.ones((n_cameras, N_CAMERA), dtype=bool)
    free[:, 4] = params.skew
    free[:, 11:16] = [term in params.lens_terms for term in LENS_TERMS]
    if fixed_pose is not None:
        free[fixed_pose, 5:11] = False
    return free


def adjust_bundle(
    cameras: tuple[Camera, ...],
    observations: WandObservations,
    markers_mm: ArrayLike,
    wand: WandPoses,
    control: ControlPoints | None = None,
    params: BundleParams = DEFAULT_PARAMS,
    fixed_pose: int | None = None,
) -> BundleResult:
    """Adjust cameras, lenses and wand poses to the observed wand (and control) images.

    Parameters
    ----------
    cameras : tuple of Camera
        Starting cameras (from the rods' DLT or the wand's initialisation).
    observations : WandObservations
        Wand marker images; every field ``0 .. len(wand) - 1`` must be seen by at least
        two cameras.
    markers_mm : array_like
        The wand's marker positions along its axis (mm), ``[wand] markers_mm``.
    wand : WandPoses
        Starting wand pose per field.
    control : ControlPoints, optional
        Points of known lab position; they fix the lab frame and scale.
    params : BundleParams
        Lens terms, skew, robust loss, outlier limits, tolerances, solver.
    fixed_pose : int, optional
        Camera whose rotation and translation are held (the gauge, when there are no
        control points).

    Returns
    -------
    BundleResult

    Raises
    ------
    KisscalError
        When the adjustment produces non-finite parameters.
    """
    offsets = centred_offsets(markers_mm)
    state = State.of(cameras, wand.centre_mm, wand.direction)
    free = free_unknowns(len(cameras), params, fixed_pose)
    keep = np.ones(len(observations), dtype=bool)
    for _ in range(3):  # later passes without the outliers of the one before
        problem = _problem(
            observations.subset(keep), offsets, control, len(cameras), len(wand.centre_mm)
        )
        state, iterations, message = _run(problem, state, free, params)
        xyz = wand_points(state, observations.field, offsets[observations.marker])
        res = observations.uv_px - project(state, observations.camera, xyz, False)[0]
        norm = np.linalg.norm(res, axis=1)
        sigma = 1.4826 * float(np.median(norm[keep]))
        new_keep = norm <= max(params.outlier_px, params.outlier_sigmas * sigma)
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    if not all(np.all(np.isfinite(a)) for a in (state.intrinsics, state.t, state.centre_mm)):
        raise EstimationFailed(
            "wand calibration: the bundle adjustment diverged (non-finite values)"
        )
    ctrl = np.zeros((0, 2))
    if control is not None and len(control):
        ctrl = control.uv_px - project(state, control.camera, control.xyz_mm, False)[0]
    poses = WandPoses(state.centre_mm, state.direction)
    return BundleResult(state.cameras(), poses, res, keep, ctrl, iterations, message)


def variance_components(
    result: BundleResult,
    observations: WandObservations,
    markers_mm: ArrayLike,
    control: ControlPoints,
    group: NDArray[np.int64],
    params: BundleParams = DEFAULT_PARAMS,
) -> tuple[NDArray[np.float64], float]:
    """The noise variance (px^2 per coordinate) of an image of each kind of observation,
    unweighted, that an adjustment's residuals show, each over its own redundancy
    (Förstner 1979).

    Each group's squared residuals (robust weights included) are divided by its count
    less the unknowns it determines, so that no variance is lowered by what the
    adjustment fitted to it: the rods' few markers, which alone fix the lab frame, would
    otherwise look far more precise than they are. The control points' share of each
    camera's unknowns is exact (:func:`kisscal.bundle.solve.control_share`); a field's
    own unknowns (a wand's 5, a free point's 3) are split over its observations, and the
    rest of each camera's over that camera's observations, so a group may hold any rows
    (a kind, a camera, a kind in one camera). Reweighing each kind by the inverse of its variance
    and adjusting again is Helmert's variance component estimation (Förstner 1979;
    Koch 1999, section 3.6).

    Parameters
    ----------
    result : BundleResult
    observations : WandObservations
        As adjusted (with their weights).
    markers_mm : array_like
    control : ControlPoints
        As adjusted (with their weight).
    group : ndarray of int, shape (len(observations),)
        Each observation's group (0, 1, ...).
    params : BundleParams

    Returns
    -------
    groups_px2 : ndarray, shape (max(group) + 1,)
    control_px2 : float
        NaN where a kind has no redundancy left.
    """
    keep = result.inlier
    obs = observations.subset(keep)
    sizes = len(result.cameras), len(result.wand.centre_mm)
    problem = _problem(obs, centred_offsets(markers_mm), control, *sizes)
    state = State.of(result.cameras, result.wand.centre_mm, result.wand.direction)
    free = free_unknowns(len(result.cameras), params, None)
    loss = Loss(params.loss, params.loss_scale_px)
    share = control_share(problem, state, free, loss)
    g = group[keep]
    n = np.bincount(g)
    w = np.ones(len(g)) if obs.weight is None else obs.weight
    r = result.residuals_px[keep]
    robust = loss.cost(np.sqrt(w)[:, None] * r)[1]
    redundancy = 2 * n - np.bincount(g, _unknowns_per_row(obs, markers_mm, free, share), len(n))
    squares = np.bincount(g, robust * np.sum(r * r, axis=1), len(n))
    c = result.control_residuals_px
    ctrl = float(np.sum(loss.cost(np.sqrt(control.weight) * c)[1] * np.sum(c * c, axis=1)))
    with np.errstate(divide="ignore", invalid="ignore"):
        groups = np.where(redundancy > 0, squares / redundancy, np.nan)
    red_ctrl = 2 * len(c) - share.sum()
    return groups, ctrl / red_ctrl if red_ctrl > 0 else float("nan")


def _unknowns_per_row(
    obs: WandObservations,
    markers_mm: ArrayLike,
    free: NDArray[np.bool_],
    control_share: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Each observation's share of the unknowns it helps determine: its field's (a free
    point's centre, 3; a wand's centre and direction, 5) over the field's observations,
    and its camera's free unknowns less the control points' share of them over the
    camera's observations. Any grouping of the observations (by kind, by camera) then
    gets the unknowns its own rows fit; an equal split, where a precise image in fact
    fixes more of its point than a noisy one (synthetic rig, four cameras at 0.02 to
    0.1 px: each camera's noise within 17 %, :func:`variance_components`)."""
    offsets = centred_offsets(markers_mm)[obs.marker]
    moving = np.zeros(int(obs.field.max()) + 1, bool)
    moving[obs.field[offsets != 0.0]] = True
    per_field = np.bincount(obs.field, minlength=len(moving))
    per_camera = np.bincount(obs.camera, minlength=len(free))
    on_camera = (free.sum(axis=1) - control_share) / np.maximum(per_camera, 1)
    on_field = (3.0 + 2.0 * moving) / np.maximum(per_field, 1)
    return on_field[obs.field] + on_camera[obs.camera]


def _problem(
    obs: WandObservations,
    offsets: NDArray[np.float64],
    control: ControlPoints | None,
    n_cameras: int,
    n_fields: int,
) -> Problem:
    seen = np.bincount(obs.field, minlength=n_fields)
    if np.any(seen == 0):
        raise EstimationFailed(
            f"wand calibration: {int(np.sum(seen == 0))} wand fields have no observation left"
        )
    order = np.lexsort((obs.camera, obs.field))
    o = obs.subset(order)
    c = (
        control
        if control is not None
        else ControlPoints(
            np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, np.int64)
        )
    )
    return Problem(
        o.field,
        o.camera,
        offsets[o.marker],
        o.uv_px,
        c.camera,
        c.xyz_mm,
        c.uv_px,
        n_cameras,
        n_fields,
        c.weight,
        o.weight,
    )


def _run(
    problem: Problem, state: State, free: NDArray[np.bool_], params: BundleParams
) -> tuple[State, int, str]:
    loss = Loss(params.loss, params.loss_scale_px)
    if params.solver == "schur":
        return levenberg_marquardt(
            problem, state, free, loss, params.tolerance, params.max_iterations
        )
    return _least_squares(problem, state, free, params)


def _least_squares(
    problem: Problem, state: State, free: NDArray[np.bool_], params: BundleParams
) -> tuple[State, int, str]:
    """The same adjustment by :func:`scipy.optimize.least_squares` (sparse pattern, FD)."""
    n_cam = int(free.sum())
    F = problem.n_fields

    def unpack(x: NDArray[np.float64]) -> State:
        d_cam = np.zeros(free.shape)
        d_cam[free] = x[:n_cam]
        return state.moved(d_cam, x[n_cam:].reshape(F, N_WAND))

    def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
        s = unpack(x)
        xyz = wand_points(s, problem.field, problem.offsets)
        r = project(s, problem.camera, xyz, False)[0] - problem.uv_px
        if problem.weight is not None:
            r = r * np.sqrt(problem.weight)[:, None]
        cr = project(s, problem.control_camera, problem.control_xyz_mm, False)[0]
        cr = np.sqrt(problem.control_weight) * (cr - problem.control_uv_px)
        return np.concatenate([r.ravel(), cr.ravel()])

    pattern = _sparsity(problem, free)
    sol = scipy.optimize.least_squares(
        fun,
        np.zeros(n_cam + N_WAND * F),
        jac_sparsity=pattern,
        method="trf",
        loss=params.loss,
        f_scale=params.loss_scale_px,
        x_scale="jac",
        ftol=params.tolerance,
        xtol=params.tolerance,
        gtol=params.tolerance,
        max_nfev=params.max_iterations,
    )
    return unpack(sol.x), int(sol.nfev), str(sol.message)


def _sparsity(problem: Problem, free: NDArray[np.bool_]) -> scipy.sparse.csr_matrix:
    """Which unknowns each residual depends on: its camera's free ones and its field's five."""
    n_cam = int(free.sum())
    column = np.full(free.shape, -1)
    column[free] = np.arange(n_cam)
    cams = np.concatenate([problem.camera, problem.control_camera])
    per_camera = free.sum(axis=1)
    rows, cols = [], []
    for xy in (0, 1):
        rows.append(np.repeat(2 * np.arange(len(cams)) + xy, per_camera[cams]))
        cols.append(column[cams][free[cams]])
        wand_rows = 2 * np.arange(len(problem.camera)) + xy
        rows.append(np.repeat(wand_rows, N_WAND))
        cols.append((n_cam + N_WAND * problem.field[:, None] + np.arange(N_WAND)).ravel())
    r, c = np.concatenate(rows), np.concatenate(cols).astype(np.int64)
    shape = (2 * len(cams), n_cam + N_WAND * problem.n_fields)
    return scipy.sparse.csr_matrix((np.ones(len(r), np.int8), (r, c)), shape=shape)
