"""Fill at a trajectory's ends (kisscal.tracking.fill_ends, the "end" fill of
kisscal.tracking.fill_passes.FILLS) against truth."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project_rows
from kisscal.tracking import FILLED_RIGID, TrackingParams, is_filled, spare_blobs
from kisscal.tracking.fill_ends import chain_end_fill
from kisscal.tracking.gaps import fill_gaps_logged
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_rayfill import rig

NAMES = ("A", "B", "C", "D")


def _filled_error(out, xyz: np.ndarray, track: int) -> tuple[np.ndarray, np.ndarray]:
    """Fields of ``track``'s filled samples and their errors (mm) against ``xyz``."""
    rows = np.flatnonzero(is_filled(out.status) & (out.track == track))
    f = out.field[rows]
    return f, np.linalg.norm(out.xyz_mm[rows] - xyz[track, f], axis=1)


def test_end_fill_carries_a_marker_hidden_at_both_ends_by_its_segment():
    xyz = rigid_body(seed=2, noise_mm=0.2)
    tracks = _tracks_of(xyz, {3: slice(0, 40), 1: slice(250, 300)})
    out, fills = fill_gaps_logged(tracks, TrackingParams(), labels=NAMES)
    f, err = _filled_error(out, xyz, 3)
    assert set(f.tolist()) == set(range(40))  # the start, back to the first field
    assert np.sqrt(np.mean(err**2)) < 1.0
    f1, err1 = _filled_error(out, xyz, 1)
    assert set(f1.tolist()) == set(range(250, 300))
    assert np.sqrt(np.mean(err1**2)) < 1.0
    assert all(g.status == FILLED_RIGID for g in fills)
    # without names, or for an unlabelled track, the ends stay open
    assert not is_filled(fill_gaps_logged(tracks, TrackingParams())[0].status).any()
    skip = fill_gaps_logged(tracks, TrackingParams(), labels=NAMES, unlabelled=(3,))[0]
    assert not np.isin(skip.field[is_filled(skip.status)], np.arange(40)).any()


def test_end_fill_stops_where_the_segment_is_lost_and_at_the_same_name():
    xyz = rigid_body(seed=3, noise_mm=0.2)
    # two of the three partners lost before field 20: only fields 20-59 are carried
    tracks = _tracks_of(xyz, {3: slice(0, 60), 0: slice(0, 20), 1: slice(0, 20)})
    out = fill_gaps_logged(tracks, TrackingParams(), labels=NAMES)[0]
    assert set(_filled_error(out, xyz, 3)[0].tolist()) == set(range(20, 60))
    # the same name on another track with samples right before the end: nothing filled
    out = fill_gaps_logged(tracks, TrackingParams(), labels=("A", "B", "C", "C"))[0]
    rows = is_filled(out.status) & (out.track == 3)
    assert not rows.any()


def test_end_fill_refused_when_the_segment_does_not_carry_the_marker():
    xyz = rigid_body(seed=4, noise_mm=0.2)
    t = np.arange(xyz.shape[1])
    xyz[3] += np.stack([60 * np.sin(t / 9), 30 * np.cos(t / 5), 0 * t], 1)  # not rigid
    tracks = _tracks_of(xyz, {3: slice(0, 40)})
    out = fill_gaps_logged(tracks, TrackingParams(), labels=NAMES)[0]
    assert not is_filled(out.status).any()


def test_end_fill_keeps_track_numbers_so_names_stay():
    body = rigid_body(seed=5, noise_mm=0.2)
    t = np.arange(body.shape[1])
    other = body[0] + np.stack([300 * np.sin(t / 20), 500 + 0 * t, 100 * np.cos(t / 15)], 1)
    xyz = np.concatenate([body, other[None]])
    # tracks are numbered by first field: the other marker (from field 20) is 3, the
    # body's fourth (from field 40) is 4; filled back to field 0, it would come first
    tracks = _tracks_of(xyz, {4: slice(0, 20), 3: slice(0, 40)})
    truth = xyz[[0, 1, 2, 4, 3]]
    out = fill_gaps_logged(tracks, TrackingParams(), labels=(*NAMES, "E"), unlabelled=(3,))[0]
    assert out.field[out.track == 4].min() == 0
    for k in range(5):
        rows = out.track == k
        err = np.linalg.norm(out.xyz_mm[rows] - truth[k, out.field[rows]], axis=1)
        assert err.max() < 5.0


def _two_cameras_see(xyz: np.ndarray, marker: int, fields: slice, cams: int, seed: int):
    """Spare blobs of ``marker`` over ``fields`` in the first ``cams`` of two cameras 90
    degrees apart (0.05 px noise), and three noise blobs per camera and field."""
    f = np.arange(fields.start, fields.stop)
    dlts = rig(xyz[marker, fields].mean(axis=0))
    rng = np.random.default_rng(seed)
    field, cam, uv = [], [], []
    for c in range(len(dlts)):
        if c < cams:
            field.append(f)
            cam.append(np.full(f.size, c))
            p = project_rows(dlts, np.full(f.size, c), xyz[marker, fields])
            uv.append(p + rng.normal(0, 0.05, p.shape))
        field.append(np.repeat(f, 3))
        cam.append(np.full(3 * f.size, c))
        uv.append(rng.uniform([0, 0], [640, 480], (3 * f.size, 2)))
    return spare_blobs(np.concatenate(field), np.concatenate(cam), np.concatenate(uv), dlts)


def test_end_rays_place_a_marker_two_cameras_see_while_its_segment_is_hidden():
    xyz = rigid_body(seed=6, noise_mm=0.2)
    # marker 3 and two of its segment back at field 60, one at 40: no body to carry it
    hidden = {0: slice(0, 40), 1: slice(0, 60), 2: slice(0, 60), 3: slice(0, 60)}
    tracks = _tracks_of(xyz, hidden)
    params = TrackingParams()
    out = fill_gaps_logged(
        tracks, params, _two_cameras_see(xyz, 3, slice(0, 60), 2, 6), labels=NAMES
    )[0]
    f, err = _filled_error(out, xyz, 3)
    assert set(range(30, 60)) <= set(f.tolist())
    assert np.sqrt(np.mean(err**2)) < 1.0
    # one camera only: no point where rays meet, and no body to carry it
    one = fill_gaps_logged(
        tracks, params, _two_cameras_see(xyz, 3, slice(0, 60), 1, 6), labels=NAMES
    )[0]
    assert not np.isin(3, one.track[is_filled(one.status)])


def test_no_end_fill_when_the_body_fills_are_off():
    xyz = rigid_body(seed=2, noise_mm=0.2)
    tracks = _tracks_of(xyz, {3: slice(0, 40)})
    off = TrackingParams(max_body_fill_fields=5)
    assert not is_filled(fill_gaps_logged(tracks, off, labels=NAMES)[0].status).any()


def _ankle(seed: int) -> np.ndarray:
    """A marker on two segments (an ankle: of the shank and of the foot) and three more
    of each, the foot turning about it by up to 0.5 rad: (7, N, 3); the shank's markers
    (0-2) measured with 0.1 mm noise, the foot's (4-6) with 0.4 mm, the ankle (3) 0.1 mm."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    shank = rigid_body(seed=seed)
    t = np.arange(shank.shape[1]) / 100.0
    turn = Rotation.from_rotvec(np.stack([0.5 * np.sin(3 * t), 0.2 * np.cos(2 * t), 0 * t], 1))
    foot = np.array([[0.0, 120, -40], [0, -60, -50], [60, 0, -70]])
    xyz = np.concatenate([shank, np.stack([turn.apply(p) + shank[3] for p in foot])])
    sd = np.array([0.1, 0.1, 0.1, 0.1, 0.4, 0.4, 0.4])[:, None, None]
    return xyz + rng.normal(0, 1, xyz.shape) * sd


def test_end_fill_carries_a_marker_on_two_segments_by_the_one_measured_there():
    # the ankle lost before field 40, the shank (more rigid to it) before 50, the foot
    # measured throughout: the foot carries the ankle back to field 0 (chosen by
    # rigidity alone, the shank would, and carry nothing where it is lost)
    xyz = _ankle(seed=7)
    tracks = _tracks_of(xyz, {3: slice(0, 40), 0: slice(0, 50), 1: slice(0, 50), 2: slice(0, 50)})
    out = fill_gaps_logged(tracks, TrackingParams(), labels=tuple("ABCDEFG"))[0]
    f, err = _filled_error(out, xyz, 3)
    assert set(f.tolist()) == set(range(40))
    assert np.sqrt(np.mean(err**2)) < 1.5


def test_end_chain_places_a_marker_one_camera_sees_on_its_ray_by_its_lengths():
    xyz = rigid_body(seed=7, noise_mm=0.2)
    # marker 3's track ends at field 150 and marker 1 is lost with it: two partners
    # measured (no three-marker body), one camera still sees marker 3 to the end
    end = slice(150, xyz.shape[1])
    tracks = _tracks_of(xyz, {3: end, 1: end})
    params = TrackingParams()
    out, fills = fill_gaps_logged(tracks, params, _two_cameras_see(xyz, 3, end, 1, 7), labels=NAMES)
    f, err = _filled_error(out, xyz, 3)
    assert len(f) >= 0.9 * (end.stop - end.start)
    assert np.sqrt(np.mean(err**2)) < 1.5
    assert all(g.ray_fields == g.n_fields for g in fills if g.track == 3)
    # one partner only: nothing checks the depth its length gives, the end stays open
    lone = _tracks_of(xyz, {3: end, 2: end, 1: end})
    got = fill_gaps_logged(lone, params, _two_cameras_see(xyz, 3, end, 1, 7), labels=NAMES)[0]
    assert not np.isin(3, got.track[is_filled(got.status)])


def _merged_in_one_camera(seed: int):
    """Marker 4 of a rigid body (and a fifth marker, 0, moving about it) with the body's
    markers 2-4 back at field 60 and 1 at 40; two cameras 90 degrees apart see marker 4
    from the start, camera 1 only in one blob with marker 0's image (2.5 px from it,
    their centroid weighted by area, 1 / depth²), camera 0 apart. Truth (5, n, 3),
    tracks and the spare blobs."""
    body = rigid_body(seed=seed, noise_mm=0.2)
    start, n = slice(0, 60), body.shape[1]
    dlts = rig(body[3, start].mean(axis=0))
    step = project_rows(dlts, [1, 1], np.stack([body[3, 30], body[3, 30] + [1.0, 0, 0]]))
    r = 2.5 / np.linalg.norm(step[1] - step[0])  # mm per 2.5 px in camera 1
    turn = np.arange(n) / 7.0
    other = body[3] + r * np.stack([np.cos(turn), 2.4 + 0 * turn, np.sin(turn)], 1)
    xyz = np.concatenate([other[None], body])
    tracks = _tracks_of(xyz, {1: slice(0, 40), 2: start, 3: start, 4: start})
    cams = np.repeat([0, 1], 60)
    images = project_rows(dlts, cams, np.concatenate([xyz[4, start]] * 2))
    shared = project_rows(dlts, np.ones(60, dtype=int), xyz[0, start])
    w_own = 1.0 / (xyz[4, start] @ dlts[1, 8:11] + 1.0) ** 2
    w_other = 1.0 / (xyz[0, start] @ dlts[1, 8:11] + 1.0) ** 2
    images[60:] = (w_own[:, None] * images[60:] + w_other[:, None] * shared) / (w_own + w_other)[
        :, None
    ]
    uv = images + np.random.default_rng(seed).normal(0, 0.05, images.shape)
    f = np.arange(60)
    return xyz, tracks, lambda: spare_blobs(np.r_[f, f], cams, uv, dlts)


def test_end_rays_take_a_known_marker_out_of_a_blob_merged_with_it():
    xyz, tracks, spare = _merged_in_one_camera(seed=9)
    names = ("E", *NAMES)
    out = fill_gaps_logged(tracks, TrackingParams(), spare(), labels=names)[0]
    f, err = _filled_error(out, xyz, 4)
    assert set(f.tolist()) == set(range(60))
    assert np.sqrt(np.mean(err**2)) < 1.0
    # the merged blob's centroid as the marker's image: its ray misses by millimetres
    raw = fill_gaps_logged(tracks, TrackingParams(ray_merge_px=0.01), spare(), labels=names)[0]
    assert np.sqrt(np.mean(_filled_error(raw, xyz, 4)[1] ** 2)) > 2.0


def test_end_chain_takes_the_placed_row_of_a_name_no_track_took_as_a_partner():
    # as above with one partner measured (marker 0); marker 2 no track took, placed on
    # one camera's rays (1 mm along them): its row is the second partner (kiss 3 seed
    # 323: a heel on one camera, its toe measured, its ankle placed)
    xyz = rigid_body(seed=7, noise_mm=0.2)
    end = slice(150, xyz.shape[1])
    dense = xyz[[0, 3]].copy()
    dense[1, end] = np.nan
    rng = np.random.default_rng(7)
    row = xyz[2:3] + rng.normal(0, 1.0 / np.sqrt(3), xyz[2:3].shape)
    errors = np.r_[np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan), np.ones((1, len(row[0])))]
    spare, params = _two_cameras_see(xyz, 3, end, 1, 7), TrackingParams()
    assert chain_end_fill(dense, 1, end.start, end.stop, spare, params, 1, errors[:2]) is None
    got = chain_end_fill(dense, 1, end.start, end.stop, spare, params, 1, errors, row)
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.9 * (end.stop - end.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, end][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < min(1.5, np.sqrt(np.mean(got.sd_mm[placed] ** 2)) + 0.5)
    assert 2 in got.partners  # the placed row, numbered after the tracks
