"""Single-camera fill with the depth from the segment's lengths smoothed across the gap
(kisscal.tracking.fill_sphere), against truth."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project_rows
from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_sphere import MIN_COS, smooth_depth, sphere_depth_fill, sphere_roots
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_raychain import GAP, _dense
from tests.tracking.test_rayfill import _look_at

PARAMS = TrackingParams()


def test_a_ray_meets_a_sphere_at_two_depths_and_none_near_tangent():
    centre, d = np.zeros((2, 3)), np.array([[0.0, 0, 1], [0.0, 0, 1]])
    partners = np.array([[30.0, 0, 1000], [99.8, 0, 1000]])  # the second nearly tangent
    roots, sd = sphere_roots(centre, d, partners, np.array([50.0, 100.0]), np.ones(2))
    assert np.allclose(roots[0], [960.0, 1040.0])
    assert np.isclose(sd[0], 1.0 / 0.8)  # cos of the ray to the partner: 40 / 50
    assert np.sqrt(100.0**2 - 99.8**2) / 100.0 < MIN_COS
    assert np.all(np.isnan(roots[1])) and np.isnan(sd[1])


def test_the_depth_smoother_bridges_a_straight_path_exactly_and_is_sure_near_data():
    idx = np.r_[0:5, 25:30]
    mean, sd = smooth_depth(30, idx, 1000.0 + 2.0 * idx, np.full(idx.size, 0.5), 1.0)
    assert np.allclose(mean, 1000.0 + 2.0 * np.arange(30))
    assert sd[15] > 5 * sd[2]  # the middle of the gap knows least
    # a datum in the gap pins it there
    idx2 = np.r_[idx, 15]
    _, sd2 = smooth_depth(30, idx2, 1000.0 + 2.0 * idx2, np.full(idx2.size, 0.5), 1.0)
    assert sd2[15] < 0.6


def _one_camera(xyz: np.ndarray, cam_at: np.ndarray, seed: int, marker: int = 3) -> tuple:
    """DLT of a camera at ``cam_at`` (offset from the marker's mean in the gap) and its
    blobs of ``marker`` through the gap, plus two noise blobs a field."""
    target = xyz[marker, GAP].mean(axis=0)
    dlts = _look_at(target + cam_at, target)[None]
    fields = np.arange(GAP.start, GAP.stop)
    rng = np.random.default_rng(seed)
    uv = project_rows(dlts, np.zeros(fields.size, dtype=int), xyz[marker, GAP])
    noise = rng.uniform([0, 0], [640, 480], (2 * fields.size, 2))
    return (
        dlts,
        np.r_[fields, np.repeat(fields, 2)],
        np.r_[uv + rng.normal(0, 0.05, uv.shape), noise],
    )


def test_a_marker_one_camera_sees_with_one_partner_is_placed_by_its_length():
    xyz = rigid_body(seed=5, noise_mm=0.2)
    # marker 3 seen by one camera; of its segment only marker 0 is measured: its
    # length puts marker 3 on a sphere the ray meets twice, the path picks the root
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    dlts, f, uv = _one_camera(xyz, np.array([1500.0, -1500.0, 2500.0]), 5)
    spare = spare_blobs(f, np.zeros(f.size), uv, dlts)
    got = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.8 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0
    assert np.all(got.sd_mm[placed] <= PARAMS.ray_depth_max_error_mm)
    assert got.partners == (0,)


def test_fields_where_a_second_camera_s_blob_is_off_the_point_are_not_placed():
    xyz = rigid_body(seed=9, noise_mm=0.2)
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    d1, f1, uv1 = _one_camera(xyz, np.array([1500.0, -1500.0, 2500.0]), 9)
    # a second camera's blob, a merge 7 mm off the marker, in the first half of the gap
    off = xyz.copy()
    off[3] += [0.0, 6.0, -4.0]
    d2, f2, uv2 = _one_camera(off, np.array([-2500.0, -1500.0, 600.0]), 10)
    half = f2 < (GAP.start + GAP.stop) // 2
    spare = spare_blobs(
        np.r_[f1, f2[half]],
        np.r_[np.zeros(f1.size), np.ones(half.sum())],
        np.r_[uv1, uv2[half]],
        np.concatenate([d1, d2]),
    )
    got = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    n = (GAP.stop - GAP.start) // 2
    assert not placed[:n].any()  # the two cameras disagree there: neither blob is sure
    assert placed[n:].sum() >= 0.8 * n
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0


def test_a_partner_seen_with_the_marker_in_few_fields_does_not_place_it():
    xyz = rigid_body(seed=5, noise_mm=0.2)
    n = xyz.shape[1]
    # marker 0 seen with marker 3 in under half of 3's fields: its length may hold only
    # in that phase (a joint held still), so it fixes no depth
    hide0 = slice(GAP.stop + 5, n)
    assert (GAP.start + 5) < 0.5 * (n - (GAP.stop - GAP.start))
    dense = _dense(_tracks_of(xyz, {0: hide0, 1: slice(5, n), 2: slice(5, n), 3: GAP}))
    dlts, f, uv = _one_camera(xyz, np.array([1500.0, -1500.0, 2500.0]), 5)
    spare = spare_blobs(f, np.zeros(f.size), uv, dlts)
    assert sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS) is None
    # seen together throughout, the same gap is placed
    dense = _dense(_tracks_of(xyz, {1: slice(5, n), 2: slice(5, n), 3: GAP}))
    assert sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS) is not None


def test_a_fit_that_misses_samples_placed_beside_it_places_nothing():
    xyz = rigid_body(seed=5, noise_mm=0.2)
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    measured = np.isfinite(dense[3, :, 0])
    dlts, f, uv = _one_camera(xyz, np.array([1500.0, -1500.0, 2500.0]), 5)
    spare = spare_blobs(f, np.zeros(f.size), uv, dlts)
    lo = GAP.start + 5
    # the gap's first five fields placed by another fill: on truth, the fit agrees
    dense[3, GAP.start : lo] = xyz[3, GAP.start : lo]
    got = sphere_depth_fill(dense, 3, lo, GAP.stop, spare, PARAMS, measured)
    assert got is not None and np.isfinite(got.sd_mm).sum() >= 0.8 * (GAP.stop - lo)
    # placed 20 mm off along the camera's sight (another marker's blob): the fit,
    # following its own blobs, contradicts them
    sight = xyz[3, GAP.start : lo] - spare.centres[0]
    sight /= np.linalg.norm(sight, axis=1)[:, None]
    dense[3, GAP.start : lo] = xyz[3, GAP.start : lo] + 20.0 * sight
    assert sphere_depth_fill(dense, 3, lo, GAP.stop, spare, PARAMS, measured) is None


def test_a_placed_partner_s_error_counts_in_the_depth_not_in_the_choice_of_roots():
    xyz = rigid_body(seed=5, noise_mm=0.2)
    dlts, f, uv = _one_camera(xyz, np.array([1500.0, -1500.0, 2500.0]), 5)
    spare = spare_blobs(f, np.zeros(f.size), uv, dlts)
    for shift, placed in (([3.0, -3.0, 0.0], True), ([0.0, 3.0, 3.0], False)):
        # the only partner placed by another fill through the gap, 4.2 mm off
        dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
        dense[0, GAP] += shift
        known = np.isfinite(dense[:, :, 0])
        known[0, GAP] = False
        as_measured = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
        got = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, known=known)
        if not placed:  # its roots miss the path: refused, as a measured partner's
            assert as_measured is None and got is None
            continue
        assert as_measured is not None and got is not None
        ok = np.isfinite(got.sd_mm)
        assert np.array_equal(ok, np.isfinite(as_measured.sd_mm))
        assert np.allclose(got.xyz_mm[ok], as_measured.xyz_mm[ok])  # the same roots
        err = np.sqrt(np.mean(np.sum((got.xyz_mm[ok] - xyz[3, GAP][ok]) ** 2, axis=1)))
        # taken as measured, the partner's error is missed: 3.0 mm off expecting 0.95
        assert err > 2.0 * np.sqrt(np.mean(as_measured.sd_mm[ok] ** 2))
        assert err < 1.5 * np.sqrt(np.mean(got.sd_mm[ok] ** 2))


def _two_placed(cut: dict, expect: float) -> tuple:
    """Marker 3 of a rigid body through GAP seen by one camera, markers 0 and 1 (the
    ones not ``cut``) placed by another fill 0.4 mm off, which expects ``expect`` mm:
    the sphere fill with the bound for a placed partner, and with what its fill expects."""
    xyz = rigid_body(seed=5, noise_mm=0.2)
    dlts, f, uv = _one_camera(xyz, np.array([1500.0, -1500.0, 2500.0]), 5)
    spare = spare_blobs(f, np.zeros(f.size), uv, dlts)
    dense = _dense(_tracks_of(xyz, cut))
    dense[:2, GAP] += [0.3, -0.3, 0.0]
    known = np.isfinite(dense[:, :, 0])
    known[:2, GAP] = False
    expected = np.where(known, 0.0, np.nan)
    expected[:2, GAP] = expect
    bound = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, known=known)
    own = sphere_depth_fill(
        dense, 3, GAP.start, GAP.stop, spare, PARAMS, known=known, expected=expected
    )
    return xyz, bound, own


def test_placed_partners_that_check_each_other_count_the_error_their_fills_expect():
    xyz, bound, got = _two_placed({2: GAP, 3: GAP}, 0.5)
    assert bound is not None and got is not None
    assert len(got.partners) == 2
    ok = np.isfinite(bound.sd_mm)
    assert np.all(np.isfinite(got.sd_mm[ok]))
    assert np.allclose(got.xyz_mm[ok], bound.xyz_mm[ok])  # the same roots
    # surer than at ray_rest_max_error_mm, and still honest against truth
    assert np.all(got.sd_mm[ok] <= bound.sd_mm[ok])
    assert got.sd_mm[ok].max() < 0.7 * bound.sd_mm[ok].max()
    err = np.sqrt(np.mean(np.sum((got.xyz_mm[ok] - xyz[3, GAP][ok]) ** 2, axis=1)))
    assert err < 1.5 * np.sqrt(np.mean(got.sd_mm[ok] ** 2))
    # a fill expecting more than a placed partner may: the bound
    _, bound, loose = _two_placed({2: GAP, 3: GAP}, 10.0)
    assert np.allclose(loose.sd_mm, bound.sd_mm, equal_nan=True)
    # one placed partner alone: nothing checks what its fill expects, the bound
    _, bound, alone = _two_placed({1: GAP, 2: GAP, 3: GAP}, 0.5)
    assert bound is not None and np.allclose(alone.sd_mm, bound.sd_mm, equal_nan=True)


def test_a_second_camera_s_blob_beside_another_track_s_image_still_checks_the_point():
    xyz = rigid_body(seed=5, noise_mm=0.2)
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    # camera 0 follows another marker's blob 10 mm beside marker 3 (a heel by the
    # ankle); camera 1, looking along marker 0 -> 3, sees marker 3's own blob beside
    # marker 0's image: not alone, so not taken, but its ray still says where 3 is
    wrong = xyz.copy()
    wrong[3] += [0.0, 8.0, -6.0]
    d0, f0, uv0 = _one_camera(wrong, np.array([1500.0, -1500.0, 2500.0]), 5)
    along = np.mean(xyz[3, GAP] - xyz[0, GAP], axis=0)
    d1, f1, uv1 = _one_camera(xyz, 8000.0 * along / np.linalg.norm(along), 6)
    n = GAP.stop - GAP.start
    near = np.linalg.norm(project_rows(d1, np.zeros(n, int), xyz[0, GAP]) - uv1[:n], axis=1)
    assert near.max() < 2.0 * PARAMS.ray_chain_gate_px  # crowded throughout
    spare = spare_blobs(
        np.r_[f0, f1], np.r_[np.zeros(f0.size), np.ones(f1.size)], np.r_[uv0, uv1], np.r_[d0, d1]
    )
    got = sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
    # before, placed on camera 0's blobs 10 mm off expecting 0.6-1.2 mm
    if got is not None:
        ok = np.isfinite(got.sd_mm)
        err = np.linalg.norm(got.xyz_mm[ok] - xyz[3, GAP][ok], axis=1)
        assert np.all(err <= 2.0 * got.sd_mm[ok])
