"""Finding the wand in images (before calibration) and among 3D points."""

from __future__ import annotations

import numpy as np

from kisscal.bundle.find import find_wand_images, find_wand_points
from kisscal.synth.scene import visibility
from tests.bundle.conftest import WandScene, scene

MARKERS = [0.0, 190.0, 500.0]


def test_every_whole_view_is_found_in_marker_order(wand_scene: WandScene) -> None:
    cam = wand_scene.rig[0]
    vis = visibility(cam, wand_scene.motion)
    blobs = [cam.project(wand_scene.motion.xyz_mm[f][vis[f]]) for f in range(len(vis))]
    rng = np.random.default_rng(0)
    blobs = [b[rng.permutation(len(b))] for b in blobs]  # detection order is arbitrary
    found = find_wand_images(blobs, MARKERS)
    whole = np.flatnonzero(vis.all(axis=1))
    assert set(found.field.tolist()) == set(whole.tolist())
    truth = cam.project(wand_scene.motion.xyz_mm[found.field])
    assert found.ordered.all()
    assert np.abs(found.uv_px - truth).max() < 1e-9


def test_partial_views_and_ghosts_are_left_out() -> None:
    wand = np.array([[100.0, 50.0], [138.0, 50.0], [200.0, 50.0]])
    blobs = [wand, wand[:2], np.vstack([wand, [[150.0, 120.0]]]), wand + [[0, 0], [0, 9], [0, 0]]]
    found = find_wand_images(blobs, MARKERS)
    assert found.field.tolist() == [0]  # partial, with a ghost, and bent: all refused


def test_reversed_and_symmetric_wands() -> None:
    wand = np.array([[200.0, 50.0], [138.0, 50.0], [100.0, 50.0]])
    found = find_wand_images([wand[::-1]], [500.0, 190.0, 0.0])
    assert found.uv_px[0, :, 0].tolist() == [200.0, 138.0, 100.0]
    two = find_wand_images([np.array([[10.0, 10.0], [90.0, 30.0]])], [0.0, 500.0])
    assert len(two) == 1 and not two.ordered[0]


def test_wand_among_3d_points_ignores_ghosts_and_refuses_two_wands() -> None:
    s = scene(3, 30, MARKERS)
    xyz = s.motion.xyz_mm  # (30, 3, 3)
    rng = np.random.default_rng(1)
    per_field = []
    for f in range(30):
        ghosts = rng.uniform(-1000, 1000, (2, 3)) + [0, 0, 1000]
        extra = xyz[f] + [3000.0, 0, 0] if f == 12 else ghosts  # field 12: two wands
        per_field.append(np.concatenate([extra[:1], xyz[f], extra[1:]]))
    field = np.concatenate([np.full(len(p), f) for f, p in enumerate(per_field)])
    flat = np.concatenate(per_field)
    found = find_wand_points(field, flat, MARKERS)
    assert sorted(found.field.tolist()) == [f for f in range(30) if f != 12]
    assert np.allclose(flat[found.point], xyz[found.field])
