"""Target matching from four to six clicked seeds: all visible points, no wrong match."""

from __future__ import annotations

import re

import numpy as np
import pytest

from kisscal.camera import Camera
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


def test_a_seed_off_the_image_is_no_click() -> None:
    """MyPTV writes ``-1, -1`` for a target point it was not given a click for (its
    example's cam2 seeds); such a row is left out, and a message about a bad click names
    the file's line of that click."""
    xyz, cam, uv, picked, dots = _camera_view("stepped", 2, 0)
    alone = match_target(xyz, uv, picked, dots, cam.size_px, cam.id)
    with_gap = match_target(
        xyz,
        np.vstack([uv[:2], [-1.0, -1.0], uv[2:]]),
        np.vstack([picked[:2], picked[1:]]),
        dots,
        cam.size_px,
        cam.id,
    )
    np.testing.assert_array_equal(with_gap.dot, alone.dot)
    assert with_gap.rms_px == pytest.approx(alone.rms_px)
    swapped = picked.copy()
    swapped[[1, 4]] = swapped[[4, 1]]  # two clicks given each other's names
    with pytest.raises(KisscalError, match=r"seed row (\d+) is off") as plain:
        match_target(xyz, uv, swapped, dots, cam.size_px, cam.id)
    line = int(re.search(r"seed row (\d+)", str(plain.value)).group(1))
    gap = np.vstack([uv[:1], [-1.0, -1.0], uv[1:]])  # the seeds' file with a line 3 added
    with pytest.raises(KisscalError, match=rf"seed row {line + (line > 2)} is off"):
        match_target(xyz, gap, np.vstack([swapped[:1], swapped]), dots, cam.size_px, cam.id)


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


def _split_view(seed: int, zoom: float, turn_deg: float, xyz: np.ndarray) -> Camera:
    """One quarter of a splitter's image: the rig's camera zoomed ``zoom`` times (a
    narrow view), turned ``turn_deg`` away from the target and its window moved to where
    the target's image fell, so that the optical axis meets the image plane outside it."""
    cam = target_rig(seed)[1]
    a = np.radians(turn_deg)
    turn = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    K = cam.K.copy()
    K[:2, :2] *= zoom
    turned = Camera(K, turn @ cam.R, turn @ cam.t, np.zeros_like(cam.lens), cam.id, cam.size_px)
    middle = np.median(turned.project(xyz), axis=0)
    K[:2, 2] -= middle - (np.array(cam.size_px) - 1) / 2
    return Camera(K, turned.R, turned.t, turned.lens, cam.id, cam.size_px)


def test_a_narrow_view_off_the_image_centre_is_matched_from_six_seeds() -> None:
    """A split or cropped image (OpenPTV's splitter): a pinhole centred on the image does
    not fit the seeds (they were refused as contradicting), one with its principal point
    free does. A target of three depth levels (alternate columns 100 mm apart)."""
    x, z = np.meshgrid(np.arange(-200.0, 201.0, 40.0), np.arange(300.0, 701.0, 40.0))
    xyz = np.column_stack([x.ravel(), 100.0 * (np.rint(x.ravel() / 40) % 3), z.ravel()])
    cam = _split_view(3, 3.0, 20.0, xyz)
    assert not cam.in_image(cam.K[:2, 2][None], 0.0)[0]  # the axis meets the plane outside
    rng = np.random.default_rng(3)
    truth = cam.project(xyz)
    seen = cam.in_image(truth, 10.0)
    dots = truth[seen] + rng.normal(0.0, 0.1, (int(seen.sum()), 2))
    picked = np.flatnonzero(seen)[[0, 5, 40, 61, 88, -1]]
    uv = truth[picked] + rng.normal(0.0, 0.3, (6, 2))
    m = match_target(xyz, uv, xyz[picked], dots, cam.size_px, cam.id)
    right = np.flatnonzero(seen)
    assert m.matched.sum() >= 0.98 * seen.sum() > 60
    assert np.array_equal(right[m.dot[m.matched]], np.flatnonzero(m.matched))  # none wrong
    assert m.rms_px < 0.3
    assert "principal_point" in m.terms
