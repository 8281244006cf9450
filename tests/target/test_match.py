"""Target matching from four to six clicked seeds: all visible points, no wrong match."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import DltParams
from kisscal.errors import KisscalError
from kisscal.synth.target import render_target, seed_points, target_points, target_rig
from kisscal.target.dots import find_target_dots
from kisscal.target.match import match_target


def _camera_view(kind: str, seed: int, cam_index: int):
    xyz, surfaces = target_points(kind)
    cam = target_rig(seed)[cam_index]
    rng = np.random.default_rng([seed, cam_index])
    image = render_target(cam, xyz, surfaces, rng)
    uv, picked = seed_points(cam, xyz, rng)
    return xyz, cam, uv, picked, find_target_dots(image, uv)


@pytest.mark.parametrize(("kind", "seed"), [("planar", 1), ("stepped", 1), ("stepped", 4)])
def test_all_visible_points_matched_none_wrong(kind: str, seed: int) -> None:
    xyz, cam, uv, picked, dots = _camera_view(kind, seed, 2)
    m = match_target(xyz, uv, picked, dots, cam.size_px, cam.id)
    truth = cam.project(xyz)
    ok = m.matched
    assert ok.sum() >= 0.98 * m.visible.sum()
    assert np.linalg.norm(dots[m.dot[ok]] - truth[ok], axis=1).max() < 0.5  # none wrong
    assert m.rms_px < 0.1


def test_contradicting_seeds_are_refused() -> None:
    xyz, cam, uv, picked, dots = _camera_view("stepped", 2, 0)
    swapped = picked.copy()
    swapped[[1, 4]] = swapped[[4, 1]]  # two clicks given each other's names
    with pytest.raises(KisscalError, match="contradict each other"):
        match_target(xyz, uv, swapped, dots, cam.size_px, cam.id)


def test_seeds_on_one_line_are_refused() -> None:
    xyz, cam, _, _, dots = _camera_view("stepped", 2, 0)
    row = xyz[(xyz[:, 1] == 0) & (xyz[:, 2] == 200.0)][::3][:6]
    with pytest.raises(KisscalError, match="one line"):
        match_target(xyz, cam.project(row), row, dots, cam.size_px, cam.id)


def test_four_seeds_on_one_level_of_a_stepped_target_match_it_all() -> None:
    """Coplanar seeds fix a wide view's camera (the resection needs no 3D spread)."""
    xyz, cam, _, _, dots = _camera_view("stepped", 2, 0)
    level = xyz[xyz[:, 1] == 80.0]
    corners = level[[0, 16, len(level) - 17, len(level) - 1]]
    m = match_target(xyz, cam.project(corners), corners, dots, cam.size_px, cam.id)
    truth = cam.project(xyz)
    assert m.matched.sum() >= 0.98 * m.visible.sum()
    assert np.linalg.norm(dots[m.dot[m.matched]] - truth[m.matched], axis=1).max() < 0.5


def test_three_seeds_are_refused_with_the_reason() -> None:
    xyz, cam, uv, picked, dots = _camera_view("stepped", 2, 0)
    with pytest.raises(KisscalError, match=r"at least 4 target points .* 7 numbers"):
        match_target(xyz, uv[:3], picked[:3], dots, cam.size_px, cam.id)


def test_the_sessions_dlt_limit_tells_a_flat_target() -> None:
    """``[dlt] min_spread_ratio`` decides whether a target is flat (matched through a
    homography): the stepped target (spread ratio 0.06) is a 3D one under the default
    limit, and a flat one under a limit of 0.1, where the seeds then fit no homography."""
    xyz, cam, uv, picked, dots = _camera_view("stepped", 1, 2)
    assert match_target(xyz, uv, picked, dots, cam.size_px, cam.id).matched.sum() > 150
    flat = DltParams(min_spread_ratio=0.1)
    with pytest.raises(KisscalError, match="seeds contradict each other"):
        match_target(xyz, uv, picked, dots, cam.size_px, cam.id, dlt=flat)
