"""The rods and a trial's markers adjusted together (:mod:`kisscal.bundle.points`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from kisscal.bundle import points
from kisscal.bundle.adjust import ControlPoints, WandObservations, WandPoses, adjust_bundle
from kisscal.bundle.params import BundleParams
from kisscal.bundle.points import (
    POINT,
    calibrate_on_points,
    calibrate_on_wand_and_points,
    trial_markers_weight,
    with_points,
)
from kisscal.bundle.wand import BlobTable, calibrate_on_control
from kisscal.camera import Camera
from kisscal.dlt import DltParams, calibrate_camera
from kisscal.errors import KisscalError
from kisscal.synth.wand import wand_trial
from tests.bundle.conftest import WandScene, scene
from tests.bundle.test_wand import _rods, _volume_error_mm


def _leftover_lens(wand_scene: WandScene) -> WandScene:
    """The scene's cameras with a tenth of their lens (what a grid's polynomial leaves)."""
    rig = tuple(Camera(c.K, c.R, c.t, 0.1 * c.lens, c.id, c.size_px) for c in wand_scene.rig)
    return WandScene(rig, wand_scene.motion, wand_scene.markers_mm)


def _noisy_rods(s: WandScene, noise_px: float) -> tuple[ControlPoints, list[np.ndarray]]:
    """The rods' markers imaged through the lens, with noise."""
    control, _ = _rods(s, 0.0)
    rows = [control.camera == c for c in range(len(s.rig))]
    uv = np.concatenate([s.rig[c].project(control.xyz_mm[r]) for c, r in enumerate(rows)])
    uv += np.random.default_rng(5).normal(0.0, noise_px, uv.shape)
    return ControlPoints(control.camera, control.xyz_mm, uv, control.group), rows


def test_free_points_adjust_to_their_images() -> None:
    """One-marker wands (free points) are adjusted without a singular direction."""
    K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
    R = [np.eye(3), np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])]
    cams = tuple(Camera(K, r, np.array([0.0, 0, 3000]), np.zeros(5)) for r in R)
    xyz = np.random.default_rng(0).uniform(-300, 300, (40, 3))
    f = np.arange(40)
    obs = WandObservations(
        np.r_[f, f], np.repeat([0, 1], 40), np.zeros(80, np.int64),
        np.concatenate([c.project(xyz) for c in cams]),
    )  # fmt: skip
    start = WandPoses(xyz + 5.0, np.tile([0.0, 0.0, 1.0], (40, 1)))
    params = BundleParams(lens_terms=())
    fit = adjust_bundle(cams, obs, POINT, start, fixed_pose=0, params=params)
    assert np.abs(fit.residuals_px).max() < 1e-6
    assert np.all(np.isfinite(fit.wand.direction))


def test_trial_markers_fit_the_lens_the_rods_alone_cannot(wand_scene: WandScene) -> None:
    """A small lens left over, rods imaged with 0.01 px of noise and the trial's markers
    with 0.05 px: the rods' 24 markers and the trial's markers (here the wand's, as free
    points: their spacing unused) adjusted together reconstruct other points of the
    volume better than each camera's DLT with Kolahi's radial terms fitted on the rods
    alone (0.09 against 0.32 mm)."""
    s = _leftover_lens(wand_scene)
    table = s.blobs(ideal=False, noise_px=0.05, leds=False)
    control, rows = _noisy_rods(s, 0.01)
    starts = [
        Camera.from_dlt(calibrate_camera(control.xyz_mm[r], control.uv_px[r]).L) for r in rows
    ]
    cal = calibrate_on_points(table, starts, control, s.sizes, BundleParams().on_grid())
    assert cal.resected is not None and len(cal.fields) > 300
    radial = DltParams(lens=True, lens_terms=3)
    rods = []
    for r in rows:
        fit = calibrate_camera(control.xyz_mm[r], control.uv_px[r], radial)
        rods.append(Camera.from_dlt(fit.L, kolahi=fit.lens))
    other = wand_trial(9, 100, 50.0, s.markers_mm).xyz_mm.reshape(-1, 3)
    trials = _volume_error_mm(cal.written, s.rig, other)
    alone = _volume_error_mm(rods, s.rig, other)
    assert trials < 0.5 * alone, (trials, alone)
    assert cal.control.weight > 1.0  # the rods' images are the more precise


def test_too_few_markers_seen_by_three_cameras_are_refused(wand_scene: WandScene) -> None:
    s = _leftover_lens(wand_scene)
    full = s.blobs(ideal=False, noise_px=0.05, leds=False)
    keep = full.field < 3
    table = BlobTable(full.field[keep], full.camera[keep], full.uv_px[keep], 3)
    control, rows = _noisy_rods(s, 0.01)
    starts = [
        Camera.from_dlt(calibrate_camera(control.xyz_mm[r], control.uv_px[r]).L) for r in rows
    ]
    with pytest.raises(KisscalError, match="seen by 3 cameras"):
        calibrate_on_points(table, starts, control, s.sizes, BundleParams().on_grid())


def _lens_scene(wand_scene: WandScene, terms: int) -> tuple:
    """The scene's lens with its first ``terms`` Brown terms, trial blobs (0.05 px) and
    rods (0.01 px) with their starting DLTs."""
    rig = []
    for c in wand_scene.rig:
        lens = np.where(np.arange(len(c.lens)) < terms, c.lens, 0.0)
        rig.append(Camera(c.K, c.R, c.t, lens, c.id, c.size_px))
    s = WandScene(tuple(rig), wand_scene.motion, wand_scene.markers_mm)
    control, rows = _noisy_rods(s, 0.01)
    starts = [
        Camera.from_dlt(calibrate_camera(control.xyz_mm[r], control.uv_px[r]).L) for r in rows
    ]
    return s, s.blobs(ideal=False, noise_px=0.05, leds=False), control, starts


def test_few_markers_keep_the_first_lens_term_alone(
    wand_scene: WandScene, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 25: a lens of k1 alone, 60 trial markers and the rods weighed ten times their
    estimated noise ratio, as a session calibrated on its calibration trials alone. The
    four Brown terms fit the markers no better than k1, so Akaike's criterion keeps k1
    alone, and the volume is reconstructed better than with the four terms the rods
    decide (0.16 against 0.24 mm)."""
    s, full, control, starts = _lens_scene(wand_scene, 1)
    keep = full.field < 20
    table = BlobTable(full.field[keep], full.camera[keep], full.uv_px[keep], 3)
    params = BundleParams().on_grid()
    cal = calibrate_on_points(table, starts, control, s.sizes, params, weight_factor=10.0)
    assert cal.lens_terms == ("k1",)
    # the same adjustment keeping every term (as before the choice)
    monkeypatch.setattr(points, "fewest_terms", lambda r, o, m, c, p: (r, p))
    every = calibrate_on_points(table, starts, control, s.sizes, params, weight_factor=10.0)
    other = wand_trial(9, 100, 50.0, s.markers_mm).xyz_mm.reshape(-1, 3)
    chosen = _volume_error_mm(cal.written, s.rig, other)
    four = _volume_error_mm(every.written, s.rig, other)
    assert chosen < 0.8 * four, (chosen, four)


def test_a_lens_the_markers_show_keeps_every_term(wand_scene: WandScene) -> None:
    """The scene's whole lens (k1, k2, p1, p2, k3) and its 570 trial markers: Akaike's
    criterion keeps the four terms, which reconstruct the volume better than k1 alone
    (0.079 against 0.083 mm)."""
    s, table, control, starts = _lens_scene(wand_scene, 5)
    params = BundleParams().on_grid()
    cal = calibrate_on_points(table, starts, control, s.sizes, params, weight_factor=10.0)
    assert cal.lens_terms == params.lens_terms
    k1 = replace(params, lens_terms=("k1",))
    alone = calibrate_on_points(table, starts, control, s.sizes, k1, weight_factor=10.0)
    other = wand_trial(9, 100, 50.0, s.markers_mm).xyz_mm.reshape(-1, 3)
    chosen = _volume_error_mm(cal.written, s.rig, other)
    first = _volume_error_mm(alone.written, s.rig, other)
    assert chosen < first, (chosen, first)


def _half(s: WandScene, other: bool) -> WandScene:
    """The fields of ``s`` whose wand centre lies on one side of the volume (x below the
    median; ``other``: at or above it)."""
    m = s.motion
    x = m.xyz_mm.mean(axis=1)[:, 0]
    keep = (x >= np.median(x)) if other else (x < np.median(x))
    motion = replace(m, xyz_mm=m.xyz_mm[keep], capsules_mm=m.capsules_mm[keep])
    return WandScene(s.rig, motion, s.markers_mm)


def test_with_points_keeps_the_wands_ends_and_adds_its_centre() -> None:
    markers, centre = with_points((0.0, 190.0, 500.0))
    assert markers == (0.0, 190.0, 500.0, 250.0) and centre == 3


def test_the_wand_adjusted_with_the_trials_markers_is_not_the_wand_alone(
    wand_scene: WandScene,
) -> None:
    """A wand waved in one half of the volume, a trial's markers in the other (a small lens
    left over, 0.05 px of noise, the rods' markers 0.01 px): the wand adjusted on the rods
    alone extrapolates the lens terms into the half it never saw (0.108 mm RMS on other
    points of the volume); adjusted with the trial's markers, it does as well as the rods
    and those markers (0.043 against 0.043 mm). Before issue 25's change the wand route
    dropped the trial's markers (the first)."""
    s = _leftover_lens(wand_scene)
    wand = _half(s, False).blobs(ideal=False, noise_px=0.05, leds=False)
    trial = _half(WandScene(s.rig, scene(3, 200).motion, s.markers_mm), True)
    points = trial.blobs(ideal=False, noise_px=0.05, seed=1, leds=False)
    control, rows = _noisy_rods(s, 0.01)
    starts = [
        Camera.from_dlt(calibrate_camera(control.xyz_mm[r], control.uv_px[r]).L) for r in rows
    ]
    params = BundleParams().on_grid()
    both = calibrate_on_wand_and_points(
        wand, points, starts, control, (s.markers_mm, s.ids, "w"), s.sizes, params, weight_factor=10
    )
    alone = calibrate_on_control(wand, starts, control, s.markers_mm, s.sizes, s.ids, "w", params)
    trials = calibrate_on_points(points, starts, control, s.sizes, params, weight_factor=10)
    other = wand_trial(9, 100, 50.0, s.markers_mm).xyz_mm.reshape(-1, 3)
    err = [_volume_error_mm(c.written, s.rig, other) for c in (both, alone, trials)]
    assert err[0] < 0.7 * err[1], err
    assert err[0] < 1.1 * err[2], err
    assert np.sum(both.fields >= 0) > 50 and np.sum(both.fields < 0) > 100
    assert both.markers_mm == with_points(s.markers_mm)[0]


@pytest.mark.parametrize(("rods_px", "points_px"), [(0.01, 0.05), (0.025, 0.02)])
def test_each_kind_is_weighed_by_its_noise_against_the_wands(
    wand_scene: WandScene, rods_px: float, points_px: float
) -> None:
    """Issue 25: the wand imaged with 0.05 px of noise, a trial's markers with
    ``points_px`` and the rods' markers with ``rods_px``: adjusted together, the rods and
    the trial's markers are weighed against the wand by the noise variance ratios their
    residuals show (Helmert's variance components, Förstner 1979), whatever the rods'
    weight it starts from (their and the wand's DLT residuals times ``weight_factor``).
    Before, the rods' weight was that start (4.0 and 1.2 times ``weight_factor``, against
    25 and 4) and a trial's marker weighed as a wand image (1, against 1 and 6.25)."""
    s = _leftover_lens(wand_scene)
    wand = _half(s, False).blobs(ideal=False, noise_px=0.05, leds=False)
    trial = _half(WandScene(s.rig, scene(3, 200).motion, s.markers_mm), True)
    points = trial.blobs(ideal=False, noise_px=points_px, seed=1, leds=False)
    control, rows = _noisy_rods(s, rods_px)
    starts = [
        Camera.from_dlt(calibrate_camera(control.xyz_mm[r], control.uv_px[r]).L) for r in rows
    ]
    args = (wand, points, starts, control, (s.markers_mm, s.ids, "w"), s.sizes)
    params = BundleParams().on_grid()
    for factor in (1.0, 10.0):
        cal = calibrate_on_wand_and_points(*args, params, weight_factor=factor)
        truth = (0.05 / rods_px) ** 2
        assert abs(np.log(cal.control.weight / truth)) < np.log(1.25), (factor, cal.control.weight)
        truth = (0.05 / points_px) ** 2
        assert abs(np.log(trial_markers_weight(cal) / truth)) < np.log(1.25), factor
