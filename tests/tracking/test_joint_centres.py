"""Joint centres found on the trial (kisscal.tracking.joint_centres) and the one-camera
depth fill they fix where the segment's own lengths do not, against truth."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from kisscal.dlt.model import project_rows
from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_sphere import sphere_depth_fill
from kisscal.tracking.joint_centres import _frames, _local, joint_centres, sphere_centre
from tests.tracking.test_bodyfill import _tracks_of
from tests.tracking.test_raychain import _dense
from tests.tracking.test_rayfill import _look_at

PARAMS = TrackingParams()
N = 400
GAP = slice(200, 260)
#: Pelvis markers (sacrum, right and left iliac spines) and the right hip joint centre in
#: the pelvis's frame (x forward, y left, z up; mm).
PELVIS = np.array([[-100.0, 0, 20], [60, -120, 0], [60, 120, 0]])
HIP = np.array([-10.0, -80, -80])
#: Thigh marker and knee marker in the thigh's frame, from the hip: the knee straight
#: below the thigh marker, so a camera looking across the thigh from the side sees the
#: two markers' length square to its ray.
THIGH = np.array([[0.0, -70, -200], [0.0, -70, -420]])


def walk(seed: int = 0, noise_mm: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis (3 markers) walking along x, a right thigh (2 markers) swinging about its
    hip and a tibia marker about the knee, straight half of each stride: (6, N, 3)
    markers (sacrum, iliac spines, thigh, knee, tibia) and the hip (N, 3)."""
    t = np.arange(N) / 100.0
    rng = np.random.default_rng(seed)
    pelvis = Rotation.from_euler(
        "zxy", np.stack([0.08 * np.sin(2 * t), 0.04 * np.sin(4 * t), 0.05 * np.cos(2 * t)], 1)
    )
    move = np.stack([1300.0 * t, 20 * np.sin(2 * t), 950 + 10 * np.sin(4 * t)], 1)
    thigh = pelvis * Rotation.from_euler(
        "yx", np.stack([0.45 * np.sin(2 * t + 0.3), 0.08 * np.sin(3 * t)], 1)
    )
    shank = thigh * Rotation.from_euler(
        "y", -1.2 * np.maximum(np.sin(2 * t + 1.0), 0.0)[:, None] ** 2
    )
    hip = pelvis.apply(HIP) + move
    knee = thigh.apply([0.0, 0, -420]) + hip
    xyz = np.stack(
        [pelvis.apply(p) + move for p in PELVIS]
        + [thigh.apply(p) + hip for p in THIGH]
        + [shank.apply([0.0, -60, -200]) + knee]
    )
    return xyz + rng.normal(0, noise_mm, xyz.shape), hip


def one_camera(xyz: np.ndarray, marker: int, seed: int, offset: list[float]) -> object:
    """One camera at ``offset`` from ``marker``'s mean position in the gap, seeing it
    through the gap, plus two noise blobs a field."""
    target = xyz[marker, GAP].mean(axis=0)
    dlts = _look_at(target + offset, target)[None]
    fields = np.arange(GAP.start, GAP.stop)
    rng = np.random.default_rng(seed)
    uv = project_rows(dlts, np.zeros(fields.size, dtype=int), xyz[marker, GAP])
    noise = rng.uniform([0, 0], [640, 480], (2 * fields.size, 2))
    return spare_blobs(
        np.r_[fields, np.repeat(fields, 2)],
        np.zeros(3 * fields.size),
        np.r_[uv + rng.normal(0, 0.05, uv.shape), noise],
        dlts,
    )


def _side_camera(xyz: np.ndarray, seed: int) -> object:
    """A camera 3 m to the right, at the thigh marker's height, sees it through the gap
    (its ray square to the thigh-knee line), plus two noise blobs a field."""
    return one_camera(xyz, 3, seed, [0.0, -3000, 0])


def test_a_sphere_fit_finds_the_centre_of_points_on_an_arc():
    rng = np.random.default_rng(1)
    angle = rng.uniform(-0.6, 0.6, 200)
    spread = rng.uniform(-0.1, 0.1, 200)
    pts = 250.0 * np.stack([np.sin(angle), np.sin(spread), -np.cos(angle) * np.cos(spread)], 1)
    pts = pts + [10.0, 20, 30] + rng.normal(0, 0.1, pts.shape)
    centre, radius, sd = sphere_centre(pts)
    assert np.linalg.norm(centre - [10.0, 20, 30]) < 5.0
    assert abs(radius[0] - 250.0) < 5.0 and sd[0] < 0.3
    # two markers of one segment about the same centre, at their own radii
    member = np.arange(200) % 2
    pts[member == 1] = (pts[member == 1] - [10.0, 20, 30]) * 0.6 + [10.0, 20, 30]
    centre, radius, sd = sphere_centre(pts, member)
    assert np.linalg.norm(centre - [10.0, 20, 30]) < 5.0
    assert np.allclose(radius, [250.0, 150.0], atol=5.0) and np.all(sd < 0.3)


def test_a_marker_seen_over_part_of_its_motion_alone_gets_no_centre():
    xyz, _ = walk()
    # the tibia measured only while its knee is straight (walk's flexion is nil there):
    # in the pelvis's frame it lies on a sphere about the hip then, which its truth
    # leaves when the knee bends
    straight = np.flatnonzero(np.sin(2 * np.arange(N) / 100.0 + 1.0) <= 0.0)[:60]
    hidden = np.ones(N, dtype=bool)
    hidden[straight] = False
    dense = _dense(_tracks_of(xyz[[0, 1, 2, 5]], {3: hidden}))  # the thigh not tracked
    known, r, tr, _ = _frames(dense, np.array([0, 1, 2]))
    pts, _ = _local(dense, np.array([3]), known, r, tr)
    centre, _, sd = sphere_centre(pts)
    assert sd[0] < 0.5 * PARAMS.rigid_fill_sd_mm  # a sphere fits its samples
    at = np.einsum("nij,j->ni", r, centre) + tr
    assert np.linalg.norm(xyz[5, known] - at, axis=1).std() > 10.0  # not its truth's
    # no marker of its segment keeps its distance to that point with it: no centre
    # (kiss 3 seed 303's RTIB, no partner tracked, 20 mm SD off such a sphere)
    assert joint_centres(dense, 3, PARAMS).clusters == ()


def test_the_thigh_marker_keeps_its_distance_to_the_hip_found_in_the_pelvis():
    xyz, hip = walk()
    got = joint_centres(_dense(_tracks_of(xyz, {3: GAP})), 3, PARAMS)
    assert got.clusters == ((0, 1, 2),)  # the knee keeps its length: no cluster of its
    # the thigh turns about the pelvis's hip: the point found keeps its distance to the
    # thigh marker's truth, in the gap too, and lies near the true hip
    dist = np.linalg.norm(xyz[3] - got.xyz_mm[0], axis=1)
    assert dist.std() < 1.0
    assert np.nanmax(np.linalg.norm(got.xyz_mm[0] - hip, axis=1)) < 10.0


def test_a_marker_whose_ray_is_square_to_its_segment_is_placed_by_the_hip():
    xyz, _ = walk(seed=3)
    dense = _dense(_tracks_of(xyz, {3: GAP}))
    spare = _side_camera(xyz, 3)
    got = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.8 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0 and err.max() < 2.0 * PARAMS.ray_depth_max_error_mm
    assert np.all(got.sd_mm[placed] <= PARAMS.ray_depth_max_error_mm)
    assert set(got.partners) == {0, 1, 2, 4}  # the knee and the pelvis carrying the hip
    # the pelvis hidden in the gap: the knee alone, its sphere met at a glancing angle,
    # does not fix the depth, and the spline across the gap does not either
    hidden = _dense(_tracks_of(xyz, {0: GAP, 1: GAP, 2: GAP, 3: GAP}))
    alone = sphere_depth_fill(hidden, 3, GAP.start, GAP.stop, _side_camera(xyz, 3), PARAMS)
    assert alone is None or np.isfinite(alone.sd_mm).sum() < 0.5 * placed.sum()
