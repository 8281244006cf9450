"""MDLT (Hatze's constraint) and refinement in pixels, with and without lens terms."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import (
    DltParams,
    calibrate_camera,
    compose_dlt,
    correct_lens,
    hatze_violation,
    project,
    solve_mdlt,
)
from kisscal.dlt.linear import solve_dlt
from kisscal.dlt.model import dlt_to_matrix
from kisscal.dlt.nonlinear import lens_frame, lens_offsets
from kisscal.errors import KisscalError
from tests.dlt.conftest import rod_xyz

K = np.array([[720.0, 0, 376], [0, 374.4, 145], [0, 0, 1]])
LEVEL_ALONG_Y = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
LEVEL_ALONG_MINUS_Y = np.array([[-1.0, 0, 0], [0, 0, -1], [0, -1, 0]])


def _kolahi_l1_coefficient(L):
    """Coefficient of L1 in eq. 10 of Kolahi et al.: zero means L1 cannot be eliminated."""
    b, c = L[4:7], L[8:11]
    return L[8] * (b @ c) - L[4] * (c @ c)


@pytest.mark.parametrize(
    ("R", "centre"),
    [(LEVEL_ALONG_Y, [1200.0, -3500, 1000]), (LEVEL_ALONG_MINUS_Y, [1200.0, 4900, 1000])],
)
def test_mdlt_level_camera_looking_along_y(rig, R, centre):
    L_true = compose_dlt(K, R, centre)
    # This is the pose where eliminating L1 (Kolahi's step 2) divides by zero.
    assert abs(_kolahi_l1_coefficient(L_true)) < 1e-15 * np.abs(L_true).max() ** 3
    xyz = rod_xyz(rig)
    rng = np.random.default_rng(7)
    uv = project(L_true, xyz) + rng.normal(0, 0.05, (len(xyz), 2))
    result = calibrate_camera(xyz, uv, DltParams(mdlt=True), camera="level")
    assert abs(result.constraint_linear) > 1e-6  # the noisy linear DLT violates it
    assert abs(result.constraint) < 1e-9
    assert result.method == "mdlt"
    assert result.rms_px < 0.08
    assert np.linalg.norm(result.centre_mm - centre) < 10
    np.testing.assert_allclose(result.R, R, atol=2e-3)


def test_mdlt_on_exact_data_is_the_true_camera(rig):
    xyz = rod_xyz(rig)
    for L_true in rig.L:
        L, _ = solve_mdlt(xyz, project(L_true, xyz))
        assert np.abs(project(L, xyz) - project(L_true, xyz)).max() < 1e-6
        assert abs(hatze_violation(L)) < 1e-12


def test_refinement_never_increases_the_pixel_error(rig):
    xyz = rod_xyz(rig)
    rng = np.random.default_rng(11)
    for L_true in rig.L:
        uv = project(L_true, xyz) + rng.normal(0, 0.3, (len(xyz), 2))
        linear = calibrate_camera(xyz, uv)
        refined = calibrate_camera(xyz, uv, DltParams(refine=True))
        both = calibrate_camera(xyz, uv, DltParams(mdlt=True, refine=True))
        assert refined.method == both.method == "refined"
        assert refined.rms_px <= linear.rms_px + 1e-12
        assert abs(both.constraint) < 1e-9
        assert refined.rms_px <= both.rms_px + 1e-12  # fewer constraints, smaller error


def _distort(L, lens, uv_ideal):
    """Observed pixels whose Kolahi correction gives ``uv_ideal`` (fixed-point inverse)."""
    uv = uv_ideal.copy()
    for _ in range(30):
        uv = uv_ideal - lens_offsets(uv, lens_frame(dlt_to_matrix(L)), lens)
    return uv


def test_lens_terms_are_recovered(rig):
    rng = np.random.default_rng(5)
    xyz = rng.uniform([0, 0, 0], [2400, 1400, 2000], (80, 3))
    L_true = rig.L[2]
    lens_true = np.array([-4e-7, 1e-12, 0.0, 2e-5, -1e-5])
    uv = _distort(L_true, lens_true, project(L_true, xyz)) + rng.normal(0, 0.05, (80, 2))
    assert np.abs(correct_lens(L_true, lens_true, uv) - project(L_true, xyz)).max() < 0.3
    plain = calibrate_camera(xyz, uv, DltParams(refine=True))
    lens = calibrate_camera(xyz, uv, DltParams(lens=True))
    assert plain.rms_px > 0.5
    assert lens.rms_px < 0.08
    assert lens.lens is not None and lens.lens[0] == pytest.approx(-4e-7, rel=0.05)


def test_one_radial_term_follows_a_radial_lens_and_keeps_the_rest_zero(rig):
    rng = np.random.default_rng(6)
    xyz = rng.uniform([0, 0, 0], [2400, 1400, 2000], (80, 3))
    L_true = rig.L[2]
    lens_true = np.array([-4e-7, 0.0, 0.0, 0.0, 0.0])
    uv = _distort(L_true, lens_true, project(L_true, xyz)) + rng.normal(0, 0.05, (80, 2))
    plain = calibrate_camera(xyz, uv, DltParams(refine=True))
    radial = calibrate_camera(xyz, uv, DltParams(lens=True, lens_terms=1))
    assert plain.rms_px > 0.5 and radial.rms_px < 0.08
    assert radial.lens[0] == pytest.approx(-4e-7, rel=0.05)
    assert np.all(radial.lens[1:] == 0.0)


def test_lens_needs_eleven_points(rig):
    xyz = rod_xyz(rig)[[0, 2, 4, 6, 8, 10, 12, 14, 16, 18]]
    with pytest.raises(KisscalError, match="16-parameter DLT needs at least 11"):
        calibrate_camera(xyz, project(rig.L[0], xyz), DltParams(lens=True), camera="c")


def test_linear_is_the_start_of_mdlt(rig):
    xyz = rod_xyz(rig)
    uv = project(rig.L[0], xyz)
    L0 = solve_dlt(xyz, uv)
    L, n_eval = solve_mdlt(xyz, uv, L0=L0)
    assert n_eval >= 1
    np.testing.assert_allclose(project(L, xyz), uv, atol=1e-6)


def test_lens_terms_are_radial_in_normalised_coordinates():
    # KISS-like pixels (about twice as tall as wide) with a little skew: L12 moves a pixel
    # along its ray from the principal point by k r^2, r measured in square pixels, which
    # is Brown's (and OpenCV's) radial term in normalised coordinates.
    from kisscal.dlt import compose_dlt

    fu, skew = 720.0, 0.7
    K = np.array([[fu, skew, 376.0], [0.0, 0.52 * fu, 145.0], [0.0, 0.0, 1.0]])
    L = compose_dlt(K, np.eye(3), [0.0, 0.0, -3000.0])
    centre, A = lens_frame(-3.0 * dlt_to_matrix(L))  # any scale and sign of P
    np.testing.assert_allclose(centre, [376.0, 145.0])
    np.testing.assert_allclose(A, K[:2, :2] / fu)
    uv = np.random.default_rng(1).uniform([0, 0], [752, 291], (50, 2))
    d = uv - K[:2, 2]
    xn = np.linalg.solve(K[:2, :2], d.T).T  # normalised coordinates
    k = 3e-7
    expected = d * (k * fu**2 * np.sum(xn**2, axis=1))[:, None]
    np.testing.assert_allclose(lens_offsets(uv, (centre, A), [k, 0, 0, 0, 0]), expected)


def test_lens_offsets_are_kolahis_equation_2_term_by_term():
    # Square pixels (A = I): L12..L16 as Kolahi et al. (2007, eq. 2) write them, which the
    # shared Brown implementation reproduces in its DLT form (cross terms x y at weight 1).
    rng = np.random.default_rng(2)
    uv = rng.uniform([0, 0], [752, 582], (200, 2))
    centre = np.array([370.0, 290.0])
    L12, L13, L14, L15, L16 = 2e-7, -3e-13, 4e-19, 5e-6, -7e-6
    xi, eta = (uv - centre).T
    r2 = xi**2 + eta**2
    radial = L12 * r2 + L13 * r2**2 + L14 * r2**3
    dxi = xi * radial + L15 * (r2 + 2 * xi**2) + L16 * xi * eta
    deta = eta * radial + L15 * xi * eta + L16 * (r2 + 2 * eta**2)
    got = lens_offsets(uv, (centre, np.eye(2)), [L12, L13, L14, L15, L16])
    np.testing.assert_allclose(got, np.column_stack([dxi, deta]), rtol=1e-12, atol=1e-12)


def test_an_iteration_that_cannot_start_is_a_clear_estimation_failure():
    """Non-finite residuals at the linear start (a fold of the real cavity target's points
    under the lens model) end as EstimationFailed, which the model choice skips, not as
    scipy's ValueError."""
    from kisscal.dlt.nonlinear import _solve
    from kisscal.dlt.params import DltParams
    from kisscal.errors import EstimationFailed

    def fun(theta):
        return np.r_[theta - 1.0, np.nan]

    with pytest.raises(EstimationFailed, match="camera cam2: the DLT iteration cannot start"):
        _solve(fun, np.zeros(3), DltParams(), "cam2")
    assert np.allclose(_solve(lambda t: np.r_[t - 1.0, 0.0], np.zeros(3), DltParams(), "c").x, 1)


def test_a_matrix_that_is_no_camera_has_no_lens_frame_and_says_so_quietly():
    """A linear DLT whose left 3 x 3 has rank 2 (what too flat a fold of control points
    gives) has no intrinsic matrix: its lens frame is non-finite, without a numpy warning
    (the refinement then reports a start it cannot take), while a real camera's is exact."""
    import warnings

    P_flat = np.array([[1.0, 0, 0, 5], [0, 1, 0, 7], [1, 1, 0, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        centre, A = lens_frame(P_flat)
    assert np.allclose(centre, 0.5) and not np.isfinite(A).all()
    R = LEVEL_ALONG_Y
    centre, A = lens_frame(K @ np.hstack([R, -(R @ np.array([1200.0, -3500, 1000]))[:, None]]))
    assert np.allclose(centre, K[:2, 2]) and np.allclose(A, [[1, 0], [0, K[1, 1] / K[0, 0]]])


def test_weights_act_as_repeated_points(rig):
    """A weight of k is k copies of the point; a quiet source weighed by its variance
    pulls the fit to the truth that equal weights lose among noisy points."""
    from kisscal.dlt.nonlinear import refine_dlt

    xyz = rod_xyz(rig)
    L_true = rig.L[0]
    rng = np.random.default_rng(3)
    quiet = np.arange(len(xyz)) % 2 == 0
    noise = np.where(quiet, 0.01, 1.0)[:, None] * rng.normal(0, 1.0, (len(xyz), 2))
    uv = project(L_true, xyz) + noise
    params = DltParams(refine=True, lens=True, lens_terms=3)
    k = np.where(quiet, 4, 1)
    L0 = solve_dlt(xyz, uv, params)
    weighted, lens_w, _ = refine_dlt(xyz, uv, L0, params, weights=k)
    copies, lens_c, _ = refine_dlt(np.repeat(xyz, k, 0), np.repeat(uv, k, 0), L0, params)
    np.testing.assert_allclose(weighted, copies, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(lens_w, lens_c, rtol=1e-5, atol=1e-9)
    pinhole = DltParams(refine=True)
    plain, _, _ = refine_dlt(xyz, uv, L0, pinhole)
    by_variance, _, _ = refine_dlt(xyz, uv, L0, pinhole, weights=np.where(quiet, 1e4, 1.0))
    err = [np.abs(project(L, xyz) - project(L_true, xyz)).max() for L in (plain, by_variance)]
    assert err[1] < 0.5 * err[0]


@pytest.mark.parametrize(("mdlt", "lens_terms"), [(False, 3), (True, 5), (False, 0)])
def test_refinement_jacobian_is_scipys_forward_difference(rig, mdlt, lens_terms):
    """The refinement's Jacobian, its moved points' residuals computed together, is
    scipy's default 2-point one value for value: the fit walks scipy's path to the same
    numbers in the same number of evaluations."""
    import scipy.optimize

    from kisscal.dlt.nonlinear import _forward_jacobian, _Problem

    xyz = rod_xyz(rig)
    rng = np.random.default_rng(11)
    lens_true = np.array([-4e-7, 1e-12, 0.0, 2e-5, -1e-5])
    uv = _distort(rig.L[1], lens_true, project(rig.L[1], xyz)) + rng.normal(0, 0.1, (len(xyz), 2))
    params = DltParams(refine=True, mdlt=mdlt, lens=lens_terms > 0, lens_terms=max(lens_terms, 1))
    prob = _Problem(xyz, uv, solve_dlt(xyz, uv, params))
    start = prob.theta_constrained if mdlt else prob.theta_free
    theta0 = np.r_[start, np.zeros(lens_terms)]
    weight = np.repeat(rng.uniform(0.5, 2.0, len(xyz)), 2)

    def fun(theta):
        return weight * prob.geometric(theta, mdlt, params.lens)

    def rows(thetas):
        return weight * prob.geometric_rows(thetas, mdlt, params.lens)

    moved = theta0 + rng.normal(0, 1e-3, (4, theta0.size))
    assert np.array_equal(rows(moved), np.stack([fun(theta) for theta in moved]))
    fits = [
        scipy.optimize.least_squares(fun, theta0, method="lm", jac=jac)
        for jac in ("2-point", _forward_jacobian(fun, rows))
    ]
    assert np.array_equal(fits[0].jac, fits[1].jac)
    assert np.array_equal(fits[0].x, fits[1].x)
    assert fits[0].nfev == fits[1].nfev
    assert fits[0].cost < 0.5 * np.sum(fun(theta0) ** 2)  # it did fit
