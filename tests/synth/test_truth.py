"""Ground truth of the synthetic rigs: centroids, and what detection should find.

The truth centroid of a marker is the distorted projection of the sphere's centre; the
noise-free rendering must put the light of an isolated spot there. ``truth/detection.json``
(:mod:`kisscal.synth.truth`) must describe the recorded images: their grey levels, noise,
background, and the sizes of the spots a threshold at half the plateau leaves.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest

from kisscal import session
from kisscal.dlt.model import project
from kisscal.io.config import load_toml
from kisscal.synth.plan import (
    SynthPlan,
    camera_glow,
    plan_session,
    render_rods,
    render_trial,
    rod_scene,
)
from kisscal.synth.presets import synth_options
from kisscal.synth.render import Spots, concat_spots, render_scene, sphere_spots
from kisscal.synth.scene import FieldTruth, led_spots, rim_px
from kisscal.synth.truth import camera_detection_truth, spots_ranges
from tests.synth.rig_check import trial_ranges

PRESETS = ("kiss", "modern", "lowcost")


@cache
def rendered(preset: str, seed: int = 1, cam: int = 1) -> tuple[SynthPlan, list]:
    """A plan and every 4th of its first 20 walk01 fields in one camera."""
    p = plan_session(synth_options(preset, seed, fields=20))
    return p, [s for s in render_trial(p, "walk01", cam) if s[0] % 4 == 0]


def scene_of(p: SynthPlan, cam_index: int, field: int, truth: FieldTruth) -> np.ndarray:
    """The noise-free light of one field (what :func:`render_markers` draws before noise)."""
    cam, r = p.rig[cam_index], p.render
    xyz = np.nan_to_num(p.trials["walk01"].xyz_mm[field])
    s = sphere_spots(cam, xyz, r.marker_radius_mm, r.marker_peak, r.bloom_px)
    v = truth.visible
    spots = concat_spots(Spots(s.centre_px[v], s.shape[v], s.peak[v]), led_spots(cam, p.rig, r))
    return render_scene(cam.size_px, spots, r)


def centroid(image: np.ndarray, uv: np.ndarray, reach: np.ndarray) -> np.ndarray:
    (u, v), (rx, ry) = np.rint(uv).astype(int), np.ceil(reach).astype(int)
    win = image[v - ry : v + ry + 1, u - rx : u + rx + 1]
    yy, xx = np.mgrid[v - ry : v + ry + 1, u - rx : u + rx + 1]
    return np.array([(win * xx).sum(), (win * yy).sum()]) / win.sum()


def recorded_light(p: SynthPlan, cam_index: int, image: np.ndarray) -> np.ndarray:
    """A recorded image back on the 8-bit scale, its known background light removed."""
    glow = camera_glow(p, cam_index)
    return image / p.render.dn_scale - (p.render.background if glow is None else glow)


@pytest.mark.parametrize("preset", PRESETS)
def test_truth_centroids_are_the_projections_of_the_marker_centres(preset: str) -> None:
    p, shots = rendered(preset)
    cam = p.rig[1]
    errors, noisy = [], []
    for field, image, truth in shots:
        xyz = p.trials["walk01"].xyz_mm[field]
        seen = truth.visible
        np.testing.assert_allclose(truth.uv_px[seen], cam.project(xyz[seen]), atol=1e-9)
        ideal = truth.uv_ideal_px[seen]
        np.testing.assert_allclose(ideal, cam.project_ideal(xyz[seen]), atol=1e-9)
        np.testing.assert_allclose(project(cam.dlt, xyz[seen]), ideal, atol=1e-6)
        scene, light = scene_of(p, 1, field, truth), recorded_light(p, 1, image)
        for j in np.flatnonzero(truth.isolated):
            reach = truth.radii_px[j] + rim_px(p.render)
            errors.append(np.linalg.norm(centroid(scene, truth.uv_px[j], reach) - truth.uv_px[j]))
            noisy.append(np.linalg.norm(centroid(light, truth.uv_px[j], reach) - truth.uv_px[j]))
    assert len(errors) > 20
    assert max(errors) < 0.02  # the rendering puts each spot's light at its truth centroid
    # and sensor noise scatters it by the preset's noise floor
    assert np.median(noisy) < {"kiss": 0.01, "modern": 0.01, "lowcost": 0.08}[preset]


@pytest.mark.parametrize("preset", PRESETS)
def test_detection_truth_describes_the_recorded_images(preset: str) -> None:
    p, shots = rendered(preset)
    truth = camera_detection_truth(p, 1, trial_ranges([t for _, _, t in shots]))
    assert truth["pixel_aspect"] == pytest.approx(
        {"kiss": 1.94, "modern": 1, "lowcost": 1}[preset], abs=0.01
    )
    images = [im for _, im, _ in shots]
    assert all(im.dtype == (np.uint8 if truth["bit_depth"] == 8 else np.uint16) for im in images)
    assert max(int(im.max()) for im in images) <= truth["max_value"]
    level = truth["background"]["trials_and_rods"]["level_dn"]
    sigma = truth["background"]["trials_and_rods"]["noise_sigma_dn"]
    dark = images[0][np.asarray(scene_of(p, 1, shots[0][0], shots[0][2]) == 0)]
    assert level[0] - 0.5 <= np.median(dark) <= level[1] + 0.5
    if sigma[1] > 0:  # the spread of the dark pixels is the noise (and the glow's slope)
        residual = recorded_light(p, 1, images[0])[scene_of(p, 1, shots[0][0], shots[0][2]) == 0]
        assert sigma[0] * 0.9 <= residual.std() * p.render.dn_scale <= sigma[1] * 1.1
    half = truth["levels_dn"]["half"] / p.render.dn_scale
    counts = []
    for _, image, t in shots:
        white = (recorded_light(p, 1, image) >= half).astype(np.uint8)
        _, labels, stats, _ = cv2.connectedComponentsWithStats(white, connectivity=8)
        u, v = np.rint(t.uv_px[t.isolated]).astype(int).T
        counts += stats[labels[v, u], cv2.CC_STAT_AREA].tolist()
    lo, hi = truth["markers"]["trials"]["half"]["pixels"]
    assert 0.8 * lo <= min(counts) and max(counts) <= 1.2 * hi


@pytest.mark.parametrize("preset", ["modern", "lowcost"])
def test_led_rings_are_larger_than_every_marker(preset: str) -> None:
    """A facing camera's strobe ring images larger than any rod marker, at any level."""
    for seed in (1, 2, 3):
        p = plan_session(synth_options(preset, seed, fields=10))
        for ci in range(len(p.rig)):
            markers, leds, light = rod_scene(p, ci)
            led, rods = spots_ranges(light, leds, p), spots_ranges(light, markers, p)
            if led["whole"]:
                assert led["half"]["pixels"][0] > rods["low"]["pixels"][1], (seed, ci)


@pytest.fixture(scope="module")
def lowcost_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("lowcost") / "s"
    return session.synthesise(
        out, preset="lowcost", seed=4, fields=10, n_cameras=2, walking5=False, n_jobs=1
    )


def test_written_session_has_no_detection_section_and_a_detection_truth(
    lowcost_session: Path,
) -> None:
    config = load_toml(lowcost_session / "session.toml")
    assert "detection" not in config
    assert [c["size"] for c in config["cameras"]] == [[640, 480], [640, 480]]
    doc = json.loads((lowcost_session / "truth" / "detection.json").read_text())
    assert doc["preset"] == "lowcost" and [c["camera"] for c in doc["cameras"]] == ["cam1", "cam2"]
    for cam in doc["cameras"]:
        assert cam["bit_depth"] == 8 and cam["pixel_aspect"] == pytest.approx(1.0)
        trials = cam["markers"]["trials"]
        assert trials["whole"] > 20
        assert 3.5 <= trials["diameter_px"]["width"][0] <= trials["diameter_px"]["width"][1] <= 12
        assert cam["grid_dots"]["whole"] == 300 and cam["markers"]["rods"]["whole"] == 24


def test_written_lowcost_session_same_bytes_in_parallel(
    lowcost_session: Path, tmp_path: Path
) -> None:
    again = session.synthesise(
        tmp_path / "b", preset="lowcost", seed=4, fields=10, n_cameras=2, walking5=False, n_jobs=2
    )
    files = sorted(
        p.relative_to(lowcost_session) for p in lowcost_session.rglob("*") if p.is_file()
    )
    assert files == sorted(p.relative_to(again) for p in again.rglob("*") if p.is_file())
    for rel in files:
        assert (lowcost_session / rel).read_bytes() == (again / rel).read_bytes(), rel


def test_kiss_detection_truth(small_session: Path) -> None:
    doc = json.loads((small_session / "truth" / "detection.json").read_text())
    assert doc["preset"] == "kiss" and len(doc["cameras"]) == 6
    for cam in doc["cameras"]:
        assert cam["pixel_aspect"] == pytest.approx(1.94, abs=0.01)
        assert cam["noise"]["read_sigma_dn"] == 0 and cam["background"]["grid"]["level_dn"] == [
            6,
            6,
        ]
        assert cam["led_rings"]["half"]["pixels"][0] > cam["markers"]["trials"]["low"]["pixels"][1]


@pytest.mark.slow
def test_written_12_bit_modern_session(tmp_path: Path) -> None:
    """A 12-bit camera model: 16-bit PNG files holding 0..4095, described as such."""
    options = synth_options("modern", 4, fields=10, n_cameras=2)
    assert options.rig.bit_depth == 12
    out = session.synthesise(
        tmp_path / "m", preset="modern", seed=4, fields=10, n_cameras=2, walking5=False
    )
    doc = json.loads((out / "truth" / "detection.json").read_text())
    assert {c["bit_depth"] for c in doc["cameras"]} == {12}
    for kind in ("grid/cam1/000000.png", "rods/cam2/000001.png", "trials/walk01/cam1/000005.png"):
        image = cv2.imread(str(out / kind), cv2.IMREAD_UNCHANGED)
        assert image.dtype == np.uint16 and image.shape == (1024, 1280) and image.max() <= 4095
    rods, _, _ = render_rods(plan_session(options), 1)
    np.testing.assert_array_equal(
        cv2.imread(str(out / "rods/cam2/000001.png"), cv2.IMREAD_UNCHANGED), rods[1]
    )
