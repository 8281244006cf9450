"""Synthetic rigs of other labs (``kisscal.synth.presets``): geometry, sizes, determinism."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from kisscal.dlt import make_rods, recognise_rods
from kisscal.synth.cameras import volume_corners_mm
from kisscal.synth.plan import (
    SynthPlan,
    plan_session,
    render_grid,
    render_rods,
    render_trial,
    trial_visibility,
)
from kisscal.synth.presets import PRESETS, synth_options
from kisscal.synth.render import sphere_spots
from kisscal.synth.scene import grid_view, rod_conflicts

SEEDS = (1, 2, 3)


@cache
def plan(preset: str, seed: int, n_cameras: int | None = None) -> SynthPlan:
    return plan_session(synth_options(preset, seed, fields=30, n_cameras=n_cameras))


def corner_shift_px(cam) -> np.ndarray:
    w, h = cam.size_px
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=float)
    return np.linalg.norm(cam.undistort_px(corners) - corners, axis=1)


@pytest.mark.parametrize("preset", list(PRESETS))
@pytest.mark.parametrize("seed", SEEDS)
def test_image_size_pixel_aspect_and_camera_count(preset: str, seed: int) -> None:
    p = plan(preset, seed)
    models = {(w, h) for w, h, _ in PRESETS[preset].camera_models}
    assert len(p.rig) == PRESETS[preset].n_cameras == {"kiss": 6, "modern": 8, "lowcost": 4}[preset]
    for cam in p.rig:
        assert cam.size_px in models
        assert cam.K[0, 0] / cam.K[1, 1] == pytest.approx(PRESETS[preset].pixel_aspect)
        assert cam.in_image(cam.project(volume_corners_mm(p.options.rig.volume_mm))).all()
    expected_aspect = {"kiss": 1.94, "modern": 1.0, "lowcost": 1.0}[preset]
    assert PRESETS[preset].pixel_aspect == pytest.approx(expected_aspect, abs=0.01)


@pytest.mark.parametrize(
    ("preset", "least_px", "most_px"),
    [("kiss", 5.0, 10.0), ("modern", 2.0, 6.5), ("lowcost", 10.0, 14.0)],
)
def test_lens_distortion_at_the_image_corners(preset: str, least_px: float, most_px: float):
    shifts = np.concatenate(
        [corner_shift_px(c) for s in (1, 2, 3, 4, 5) for c in plan(preset, s).rig]
    )
    assert shifts.min() >= least_px and shifts.max() <= most_px


@pytest.mark.parametrize("preset", ["modern", "lowcost"])
@pytest.mark.parametrize("seed", SEEDS)
def test_marker_and_dot_images_lie_in_the_preset_bands(preset: str, seed: int) -> None:
    """Outline diameters of every marker a camera sees (trials and rods), and grid dots."""
    p = plan(preset, seed)
    lo, hi = PRESETS[preset].marker_diameter_px
    r = p.render
    rods = np.concatenate([rod.points_mm for rod in p.rods])
    for cam in p.rig:
        sizes = [2 * sphere_spots(cam, rods, r.marker_radius_mm, 1.0, r.bloom_px).radii_px]
        for name, motion in p.trials.items():
            seen = trial_visibility(p, name)[..., p.rig.index(cam)]
            spots = sphere_spots(cam, motion.xyz_mm[seen], r.marker_radius_mm, 1.0, r.bloom_px)
            sizes.append(2 * spots.radii_px)
        d = np.concatenate(sizes)
        assert lo <= d.min() and d.max() <= hi, (cam.id, d.min(), d.max())
        dots = 2 * grid_view(cam, seed, dot_radius_px=r.grid_dot_radius_px).spots.radii_px
        dlo, dhi = PRESETS[preset].grid_dot_diameter_px
        assert dlo - 1.5 <= dots.min() and dots.max() <= dhi + 1.5  # tilt and lens: +-1 px


def test_the_seed_varies_sizes_noise_and_camera_models() -> None:
    modern = [synth_options("modern", s) for s in range(1, 11)]
    assert len({o.rig.size_px for o in modern}) == 2  # 1280 x 1024 and 2048 x 2048
    assert {o.rig.bit_depth for o in modern} == {8, 10, 12}
    assert len({o.rate_hz for o in modern}) > 1
    for preset in ("modern", "lowcost"):
        radii = {round(plan(preset, s).render.marker_radius_mm, 1) for s in SEEDS}
        noise = {round(plan(preset, s).render.noise_sigma, 3) for s in SEEDS}
        dots = {round(plan(preset, s).render.grid_dot_radius_px, 3) for s in SEEDS}
        assert len(radii) == len(noise) == len(dots) == len(SEEDS), preset


@pytest.mark.parametrize("preset", ["modern", "lowcost"])
def test_trials_stay_inside_the_volume_seen_by_three_cameras(preset: str) -> None:
    from kisscal.session.synth import default_walking5_path
    from kisscal.session.synth_session import load_walking5

    path = default_walking5_path()
    for seed in SEEDS:
        options = synth_options(preset, seed)
        replay = load_walking5(path, options.rate_hz) if path else None
        p = plan_session(options, replay)
        lo, hi = (np.asarray(c) for c in options.rig.volume_mm)
        for name, motion in p.trials.items():
            xyz = motion.xyz_mm[np.isfinite(motion.xyz_mm).all(axis=-1)]
            assert np.all((xyz >= lo) & (xyz <= hi)), (name, seed)
            exists = np.isfinite(motion.xyz_mm).all(axis=-1)
            three = (trial_visibility(p, name).sum(axis=-1) >= 3)[exists].mean()
            assert three >= (0.85 if name == "walk5" else 0.9), (name, seed, three)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_same_seed_same_images_other_seed_other_images(preset: str) -> None:
    def images(seed: int) -> list[np.ndarray]:
        p = plan_session(synth_options(preset, seed, fields=10))
        trial = next(im for f, im, _ in render_trial(p, "walk01", 1) if f == 3)
        return [render_grid(p, 1)[0][0], render_rods(p, 0)[0][1], trial]

    a, b, c = images(5), images(5), images(6)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not any(np.array_equal(x, z) for x, z in zip(a, c, strict=True))


@pytest.mark.parametrize("seed", [1, 2])
def test_a_16_camera_ring_sees_every_rod_marker(seed: int) -> None:
    """Sixteen cameras around the walkway: rods hung clear of every LED ring and of each
    other, all 24 markers recognised in every camera from their (noisy) centroids."""
    p = plan("modern", seed, 16)
    assert len(p.rig) == 16 and p.rod_conflicts == 0
    rods = make_rods([(r.name, r.points_mm) for r in p.rods])
    rng = np.random.default_rng(seed)
    points = np.concatenate([r.points_mm for r in p.rods])
    for cam in p.rig:
        uv = cam.project_ideal(points) + rng.normal(0, 0.05, (len(points), 2))
        match = recognise_rods(uv, rods, camera=cam.id)
        assert match.missing == (), (cam.id, match.missing)
    three = (trial_visibility(p, "walk01").sum(axis=-1) >= 3).mean()
    assert three > 0.99


def test_crowded_small_rigs_say_how_many_rod_markers_are_hidden() -> None:
    """Sixteen webcams around a 3 m walkway cannot all see every rod marker clear."""
    p = plan("lowcost", 1, 16)
    assert p.rod_conflicts == rod_conflicts(p.rig, p.rods, p.render, line_gap_px=4.0) > 0


def test_the_kiss_preset_describes_the_rig_kisscal_always_drew() -> None:
    """``kiss`` keeps the earlier defaults (same seed, same bytes); its description in
    PRESETS must say what they are."""
    from kisscal.synth.cameras import FIELD_SIZE_PX, PIXEL_ASPECT, VOLUME_MM
    from kisscal.synth.plan import RigSpec, SynthOptions
    from kisscal.synth.render import RenderParams

    kiss, r, o = PRESETS["kiss"], RenderParams(), SynthOptions()
    assert kiss.camera_models == ((*FIELD_SIZE_PX, r.bit_depth),)
    assert kiss.pixel_aspect == pytest.approx(1 / PIXEL_ASPECT) == RigSpec().pixel_aspect
    assert (
        kiss.volume_mm == VOLUME_MM and kiss.corner_distortion_px == RigSpec().corner_distortion_px
    )
    assert kiss.blur_px == (r.blur_px, r.blur_px) and kiss.bloom_px == r.bloom_px
    assert kiss.marker_peak_dn == (r.marker_peak, r.marker_peak)
    assert kiss.led_radius_mm == r.led_radius_mm and kiss.led_flare_px == (r.led_flare_px,) * 2
    assert kiss.grid_dot_diameter_px == (2 * r.grid_dot_radius_px,) * 2
    assert kiss.grid_fill == RigSpec().grid_fill and kiss.throw_s == RigSpec().throw_s
    assert kiss.rates_hz == (o.rate_hz,) and kiss.fields == o.fields == o.stick_fields
    assert kiss.glow is None and kiss.sensor.read_noise_dn == (r.noise_sigma, r.noise_sigma)
    assert kiss.sensor.noise_pixels == r.noise_pixels
    assert kiss.sensor.streak_probability == r.streak_probability
    assert synth_options("kiss", 3) == SynthOptions(seed=3)
