"""Two markers merged in one view and apart in one other, with no trajectory to start from."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.recon.body import RigidTriangles
from kisscal.recon.epipolar import camera_centre_mm

from .rig import SIZE_PX
from .scenario import observe
from .test_hidden import SEGMENT_MM, _found, turning_segment

#: The marker set: the segment A-B and two lengths no pair here comes near.
BODY = RigidTriangles(np.array([SEGMENT_MM]), np.array([400.0]), np.array([450.0]))


def _walk(seed: int, n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Three cameras; marker A walks, B lies SEGMENT_MM from it, 4-8 degrees off camera
    1's line of sight through A (their images there 1.2-2.3 px apart: one blob), and
    camera 0 sees them apart; camera 2 sees neither. A third marker C, seen by all three
    cameras, gives the trial its points. Returns the DLTs and A, B, C (n, 3, 3)."""
    dlts, a, b = turning_segment(seed, np.linspace(4.0, 8.0, n))
    return dlts, np.stack([a, b, a + [0.0, 0.0, 300.0]], axis=1)


def _reconstruct(dlts: np.ndarray, xyz: np.ndarray, visible: np.ndarray, seed: int):
    tab = observe(dlts, SIZE_PX, xyz, visible, seed, noise_blobs=0, leds=False, merge="centroid")
    params = ReconParams(stationary_filter=False)
    return tab, reconstruct_trial(tab.field, tab.camera, tab.uv, dlts, params, body=BODY)


@pytest.mark.parametrize("seed", [0, 3])
def test_a_pair_merged_throughout_is_placed_from_its_two_pair_points(seed: int) -> None:
    # merged in camera 1 in every field: no trajectory predicts either marker (the
    # hidden passes need one), and each pair (merged blob, own blob) lands mm off
    dlts, xyz = _walk(seed)
    visible = np.ones(xyz.shape[:2] + (3,), dtype=bool)
    visible[:, :2, 2] = False
    tab, pts = _reconstruct(dlts, xyz, visible, seed)
    sep = np.linalg.norm(project(dlts[1], xyz[:, 0]) - project(dlts[1], xyz[:, 1]), axis=1)
    assert tab.n_merged == len(xyz) and sep.min() > 1.0  # one blob, two images apart
    found, ghosts = _found(pts, xyz)
    assert found[:, :2].all(axis=1).mean() >= 0.9  # both within 3 mm
    assert ghosts == 0


@pytest.mark.parametrize("seed", [0, 1])
def test_a_single_view_ray_crossing_a_markers_ray_is_not_a_merged_marker(seed: int) -> None:
    # B seen by camera 0 alone, its ray crossing A's ray of camera 1 one segment length
    # from A: the pair (A's blob, B's blob) is a point whose image in camera 1 is A's, so
    # the blob explains A alone; no second marker may be placed in it
    dlts, xyz = _walk(seed)
    a = xyz[:, 0]
    ray = a - camera_centre_mm(dlts[1])
    crossing = a + SEGMENT_MM * ray / np.linalg.norm(ray, axis=1)[:, None]
    away = crossing - camera_centre_mm(dlts[0])
    xyz[:, 1] = crossing + 300.0 * away / np.linalg.norm(away, axis=1)[:, None]
    visible = np.ones(xyz.shape[:2] + (3,), dtype=bool)
    visible[:, :2, 2] = False
    visible[:, 1, 1] = False
    tab, pts = _reconstruct(dlts, xyz, visible, seed)
    assert tab.n_merged == 0
    assert _found(pts, xyz)[1] == 0
