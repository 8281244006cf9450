"""The bundle adjustment: the sparse solver against scipy's, recovery of truth, outliers."""

from __future__ import annotations

import numpy as np

from kisscal.bundle.adjust import (
    ControlPoints,
    WandObservations,
    WandPoses,
    adjust_bundle,
    centred_offsets,
    variance_components,
)
from kisscal.bundle.model import N_CAMERA, N_WAND
from kisscal.bundle.params import BundleParams
from kisscal.bundle.solve import Problem, _Blocks, _damped_step
from kisscal.camera import Camera
from kisscal.synth.scene import rod_set, visibility
from tests.bundle.conftest import scene

MARKERS = (0.0, 190.0, 500.0)


def _problem(n_fields: int, noise_px: float, n_cameras: int = 4, seed: int = 1):
    """Truth cameras (ideal pixels), wand observations, truth wand poses and rod points."""
    s = scene(seed, n_fields, MARKERS, n_cameras)
    rng = np.random.default_rng(seed)
    rows = []
    for ci, cam in enumerate(s.rig):
        f, m = np.nonzero(visibility(cam, s.motion))
        uv = cam.project_ideal(s.motion.xyz_mm[f, m]) + rng.normal(0, noise_px, (len(f), 2))
        rows.append((f, np.full(len(f), ci), m, uv))
    obs = WandObservations(*(np.concatenate([r[i] for r in rows]) for i in range(4)))
    count = np.bincount(obs.field * n_cameras + obs.camera, minlength=n_fields * n_cameras)
    seen = (count.reshape(n_fields, n_cameras) > 0).sum(axis=1) >= 2
    keep = seen[obs.field]
    new = np.cumsum(seen) - 1
    obs = obs.subset(keep)
    obs = WandObservations(new[obs.field], obs.camera, obs.marker, obs.uv_px)
    xyz = s.motion.xyz_mm[seen]
    d = xyz[:, 2] - xyz[:, 0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    truth = WandPoses(0.5 * (xyz[:, 0] + xyz[:, 2]), d)
    pts = np.concatenate([r.points_mm for r in rod_set(seed)])
    cams = [Camera(c.K, c.R, c.t, np.zeros(5)) for c in s.rig]
    ctrl = ControlPoints(
        np.repeat(np.arange(n_cameras), len(pts)),
        np.tile(pts, (n_cameras, 1)),
        np.concatenate([c.project_ideal(pts) for c in s.rig]),
        np.tile(np.repeat(np.arange(4), 6), n_cameras),
    )
    return cams, obs, truth, ctrl


def _perturbed(cams, rng, focal=0.01, shift_mm=20.0):
    out = []
    for c in cams:
        K = c.K * np.array([[1 + focal, 1, 1], [1, 1 - focal, 1], [1, 1, 1]])
        out.append(Camera(K, c.R, c.t + rng.normal(0, shift_mm, 3), c.lens))
    return tuple(out)


def test_recovers_the_true_cameras_from_a_perturbed_start() -> None:
    cams, obs, truth, ctrl = _problem(60, 0.0)
    rng = np.random.default_rng(0)
    start = WandPoses(truth.centre_mm + rng.normal(0, 10, truth.centre_mm.shape), truth.direction)
    fit = adjust_bundle(_perturbed(cams, rng), obs, MARKERS, start, ctrl, BundleParams())
    assert np.abs(fit.residuals_px).max() < 1e-4
    for got, true in zip(fit.cameras, cams, strict=True):
        assert np.linalg.norm(got.centre_mm - true.centre_mm) < 0.01
        assert np.abs(got.K - true.K).max() < 1e-3 and np.abs(got.lens).max() < 1e-5


def test_schur_solver_reaches_scipys_minimum() -> None:
    """Same model, same (plain least-squares) loss: kisscal's solver gets at least as low
    as scipy.optimize.least_squares with the sparse pattern (which, given 80 evaluations,
    is still within 1 % of it: it converges, slowly)."""
    cams, obs, truth, _ = _problem(25, 0.1, n_cameras=3)
    start_cams = _perturbed(cams, np.random.default_rng(1), 0.005, 5.0)
    start = WandPoses(truth.centre_mm + 5.0, truth.direction)
    costs = {}
    for solver, budget in (("schur", 100), ("least_squares", 80)):
        params = BundleParams(solver=solver, loss="linear", max_iterations=budget, lens_terms=())
        fit = adjust_bundle(start_cams, obs, MARKERS, start, None, params, 0)
        costs[solver] = np.sum(fit.residuals_px[fit.inlier] ** 2)
    assert costs["schur"] <= costs["least_squares"] * (1 + 1e-9)
    assert costs["least_squares"] <= costs["schur"] * 1.01


def test_outliers_are_dropped_and_do_not_bend_the_cameras() -> None:
    cams, obs, truth, ctrl = _problem(60, 0.05)
    bad = np.arange(0, len(obs), 97)
    uv = obs.uv_px.copy()
    uv[bad] += 15.0
    broken = WandObservations(obs.field, obs.camera, obs.marker, uv)
    fit = adjust_bundle(cams, broken, MARKERS, truth, ctrl, BundleParams())
    assert not fit.inlier[bad].any() and fit.inlier.mean() > 0.97
    for got, true in zip(fit.cameras, cams, strict=True):
        assert np.linalg.norm(got.centre_mm - true.centre_mm) < 3.0


def test_offsets_are_centred_on_the_end_markers() -> None:
    assert centred_offsets([0.0, 190.0, 500.0]).tolist() == [-250.0, -60.0, 250.0]


def test_schur_step_solves_the_whole_damped_system() -> None:
    """The reduced camera system (wand unknowns eliminated field by field, Hartley &
    Zisserman A6.3) gives the step of the whole damped normal equations solved densely:
    cameras that miss fields, a held camera unknown, a field with a zero diagonal."""
    rng = np.random.default_rng(3)
    C, F = 4, 30
    seen = [np.sort(rng.choice(C, rng.integers(2, C + 1), replace=False)) for _ in range(F)]
    field = np.concatenate([np.full(len(s), f) for f, s in enumerate(seen)])
    camera = np.concatenate(seen)
    problem = Problem(
        field, camera, np.zeros(len(field)), np.zeros((len(field), 2)),
        np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 2)), C, F,
    )  # fmt: skip
    blocks = _Blocks(problem)
    a = rng.normal(size=(C, N_CAMERA, N_CAMERA))
    U = a @ a.transpose(0, 2, 1) + 40.0 * np.eye(N_CAMERA)
    b = rng.normal(size=(F, N_WAND, N_WAND))
    V = b @ b.transpose(0, 2, 1) + np.eye(N_WAND)
    V[0, 3:, :] = V[0, :, 3:] = 0.0  # a free point: its direction rows are zero
    W = 0.3 * rng.normal(size=(len(blocks.pair_start), N_CAMERA, N_WAND))
    W[blocks.pair_field == 0, :, 3:] = 0.0
    g_cam, g_wand = rng.normal(size=(C, N_CAMERA)), rng.normal(size=(F, N_WAND))
    g_wand[0, 3:] = 0.0
    free = np.ones((C, N_CAMERA), dtype=bool)
    free[1, 5] = False
    lam = 0.01
    d_cam, d_wand = _damped_step(problem, blocks, (U, V, W, g_cam, g_wand), lam, free)

    n = C * N_CAMERA
    H = np.zeros((n + F * N_WAND, n + F * N_WAND))
    for c in range(C):
        H[c * N_CAMERA : (c + 1) * N_CAMERA, c * N_CAMERA : (c + 1) * N_CAMERA] = U[c]
    for f in range(F):
        s = slice(n + f * N_WAND, n + (f + 1) * N_WAND)
        H[s, s] = V[f]
    for p, (c, f) in enumerate(zip(blocks.pair_camera, blocks.pair_field, strict=True)):
        rows, cols = (
            slice(c * N_CAMERA, (c + 1) * N_CAMERA),
            slice(n + f * N_WAND, n + (f + 1) * N_WAND),
        )
        H[rows, cols], H[cols, rows] = W[p], W[p].T
    diag = np.diag(H).copy()
    H[np.diag_indices_from(H)] += lam * diag + (diag == 0.0)
    keep = np.r_[free.ravel(), np.ones(F * N_WAND, dtype=bool)]
    step = np.zeros(len(H))
    step[keep] = np.linalg.solve(H[np.ix_(keep, keep)], -np.r_[g_cam.ravel(), g_wand.ravel()][keep])
    np.testing.assert_allclose(d_cam.ravel(), step[:n], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(d_wand.ravel(), step[n:], rtol=1e-9, atol=1e-12)


def test_variance_components_of_each_camera_recover_its_noise() -> None:
    """Förstner's (1979) variance components over groups that split every field (one
    group per camera): each camera's wand images with their own noise, the rods' with
    less, all weighed by their true noise (the point Helmert's iteration settles at), and
    each group's estimate within 25 % of its truth (17 % at most: the fields' unknowns
    split equally over their images). Before, a field's unknowns all went to the group of
    its last camera: its noise came out 2.6 times its truth, the first camera's 30 % low."""
    cams, obs, truth, ctrl = _problem(300, 0.0, n_cameras=4, seed=3)
    rng = np.random.default_rng(5)
    noise = np.array([0.02, 0.05, 0.05, 0.1])
    uv = obs.uv_px + rng.normal(size=(len(obs), 2)) * noise[obs.camera, None]
    weight = (noise[0] / noise[obs.camera]) ** 2
    obs = WandObservations(obs.field, obs.camera, obs.marker, uv, weight)
    rods_uv = ctrl.uv_px + rng.normal(0, 0.01, ctrl.uv_px.shape)
    ctrl = ControlPoints(ctrl.camera, ctrl.xyz_mm, rods_uv, ctrl.group, (noise[0] / 0.01) ** 2)
    params = BundleParams(lens_terms=(), loss="linear")
    fit = adjust_bundle(tuple(cams), obs, MARKERS, truth, ctrl, params)
    groups, rods = variance_components(fit, obs, MARKERS, ctrl, obs.camera, params)
    assert np.all(np.abs(np.log(np.sqrt(groups) / noise)) < np.log(1.25)), np.sqrt(groups)
    assert abs(np.log(np.sqrt(rods) / 0.01)) < np.log(1.15), np.sqrt(rods)
