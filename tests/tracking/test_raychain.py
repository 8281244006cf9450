"""Single-camera fill from the marker's own blob (kisscal.tracking.raychain) and unnamed
pieces joining a named trajectory's gap (labelling.pieces), against truth."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from kisscal.dlt.model import project_rows
from kisscal.tracking import FILLED_RIGID, TrackingParams, spare_blobs
from kisscal.tracking.blob_paths import parted
from kisscal.tracking.fill_depth import depth_ray_fill
from kisscal.tracking.fill_joint import joint_ray_fill
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.labelling import Labelling
from kisscal.tracking.labelling.pieces import join_gap_pieces
from kisscal.tracking.raychain import chain_fill
from kisscal.tracking.raywalk import agreed_pick, connected_picks
from kisscal.tracking.tracks import MEASURED, make_tracks
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_rayfill import _look_at

GAP = slice(100, 160)
PARAMS = TrackingParams()


def _spare(xyz: np.ndarray, seed: int) -> object:
    """A camera looking along marker 0 -> 3 (the ray crosses their length well) sees
    marker 3 through the gap, and three noise blobs a field anywhere."""
    toward = np.mean(xyz[3, GAP] - xyz[0, GAP], axis=0)
    target = xyz[3, GAP].mean(axis=0)
    dlts = _look_at(target + 3000.0 * toward / np.linalg.norm(toward) + [0, 300, 0], target)[None]
    fields = np.arange(GAP.start, GAP.stop)
    uv = project_rows(dlts, np.zeros(fields.size, dtype=int), xyz[3, GAP])
    rng = np.random.default_rng(seed)
    noise = rng.uniform([0, 0], [640, 480], (3 * fields.size, 2))
    return spare_blobs(
        np.r_[fields, np.repeat(fields, 3)],
        np.zeros(4 * fields.size),
        np.r_[uv + rng.normal(0, 0.05, uv.shape), noise],
        dlts,
    )


def test_a_marker_only_one_camera_sees_is_placed_on_its_ray_by_its_segment():
    xyz = rigid_body(seed=3, noise_mm=0.2)
    # marker 3 and two of its segment's markers hidden for 0.6 s: no rigid-body fill,
    # only marker 0 carries it; camera 0 still sees marker 3
    tracks = _tracks_of(xyz, {3: GAP, 1: GAP, 2: GAP})
    params = TrackingParams()
    out, fills = fill_gaps_logged(tracks, params, _spare(xyz, 3))
    plain, _ = fill_gaps_logged(tracks, params)
    placed = [g for g in fills if g.track == 3 and g.ray_fields and g.status == FILLED_RIGID]
    assert sum(g.n_fields for g in placed) >= 30  # where the ray crosses the length well
    for g in placed:
        rows = (out.track == 3) & (out.field >= g.first_field)
        rows &= out.field < g.first_field + g.n_fields
        err = np.linalg.norm(out.xyz_mm[rows] - xyz[3, out.field[rows]], axis=1)
        assert np.sqrt(np.mean(err**2)) < max(g.expected_error_mm, 1.0) + 0.5
        assert g.expected_error_mm <= params.ray_length_max_error_mm

    # more of the gap within 3 mm of truth than the body alone places
    def good(trk):
        rows = (trk.track == 3) & (trk.field >= GAP.start) & (trk.field < GAP.stop)
        return np.sum(np.linalg.norm(trk.xyz_mm[rows] - xyz[3, trk.field[rows]], axis=1) < 3)

    assert good(out) > good(plain) + 20


def test_without_the_marker_s_blob_nothing_is_placed_on_a_noise_ray():
    xyz = rigid_body(seed=5, noise_mm=0.2)
    tracks = _tracks_of(xyz, {3: GAP, 1: GAP, 2: GAP})
    spare = _spare(xyz, 5)
    # the marker's own blobs (each field's first: the sort is stable) used elsewhere
    spare.free[np.searchsorted(spare.field, np.arange(GAP.start, GAP.stop))] = False
    _, fills = fill_gaps_logged(tracks, TrackingParams(), spare)
    assert not any(g.ray_fields and g.track == 3 for g in fills)


def _labelling(xyz: np.ndarray, piece: slice, decoy: np.ndarray, hidden: slice = GAP) -> Labelling:
    """Markers 0-3 named A-D, D hidden in ``hidden``, its samples in ``piece`` a separate
    unnamed track, and an unnamed decoy track in the same fields."""
    tracks = _tracks_of(xyz, {3: hidden})
    f = np.arange(piece.start, piece.stop)
    fields = np.r_[tracks.field, f, f]
    track = np.r_[tracks.track, np.full(f.size, 4), np.full(f.size, 5)]
    pts = np.r_[tracks.xyz_mm, xyz[3, piece], decoy]
    n = fields.size
    joined = make_tracks(fields, track, pts, np.full((n, 3), np.nan), np.zeros(n), np.arange(n))
    return Labelling(joined, ("A", "B", "C", "D", "M1", "M2"), True, (4, 5), (), 1.0)


def test_an_unnamed_piece_inside_a_named_gap_joins_it_and_a_decoy_does_not():
    xyz = rigid_body(seed=6, noise_mm=0.2)
    decoy = xyz[3, 110:150] + [0.0, 0.0, 150.0]  # moves with the marker, 15 cm above it
    got = join_gap_pieces(_labelling(xyz, slice(110, 150), decoy), TrackingParams())
    assert got.labels.count("D") == 1 and got.unlabelled == (got.labels.index("M1"),)
    d = got.tracks.track == got.labels.index("D")
    meas = d & (got.tracks.status == MEASURED)
    assert np.isin(np.arange(110, 150), got.tracks.field[meas]).all()
    err = np.linalg.norm(got.tracks.xyz_mm[meas] - xyz[3, got.tracks.field[meas]], axis=1)
    assert err.max() < 2.0
    m1 = got.tracks.track == got.labels.index("M1")
    assert np.allclose(got.tracks.xyz_mm[m1], decoy)


def test_an_unnamed_piece_past_a_named_trajectory_s_end_joins_it_and_a_decoy_does_not():
    # modern 3 cameras seed 419: SACR seen by one camera for 22 fields, then by two and
    # three to the end of the walk as an unnamed piece; its span had no SACR sample
    xyz = rigid_body(seed=5, noise_mm=0.2)
    decoy = xyz[3, 222:] + [0.0, 0.0, 150.0]
    got = join_gap_pieces(
        _labelling(xyz, slice(222, 300), decoy, slice(200, 300)), TrackingParams()
    )
    assert got.labels.count("D") == 1 and got.unlabelled == (got.labels.index("M1"),)
    d = got.tracks.track == got.labels.index("D")
    assert np.isin(np.arange(222, xyz.shape[1]), got.tracks.field[d]).all()
    err = np.linalg.norm(got.tracks.xyz_mm[d] - xyz[3, got.tracks.field[d]], axis=1)
    assert err.max() < 2.0
    m1 = got.tracks.track == got.labels.index("M1")
    assert np.allclose(got.tracks.xyz_mm[m1], decoy)


def _ends(xyz: np.ndarray, stretch_mm: float) -> Labelling:
    """Markers 0-3 named A-D measured up to field 150; A (``stretch_mm`` farther from C)
    and C seen again from field 160 and 165 as two unnamed pieces, nothing named there."""
    tracks = _tracks_of(xyz[:, :150], {})
    away = xyz[0, 160:] - xyz[2, 160:]
    away *= stretch_mm / np.linalg.norm(away, axis=1, keepdims=True)
    pieces = [(0, 160, away[:40]), (2, 165, 0.0)]
    fields = np.concatenate([tracks.field] + [np.arange(a, 200) for _, a, _ in pieces])
    track = np.concatenate(
        [tracks.track] + [np.full(200 - p[1], 4 + k) for k, p in enumerate(pieces)]
    )
    pts = np.concatenate([tracks.xyz_mm] + [xyz[m, a:200] + up for m, a, up in pieces])
    n = fields.size
    joined = make_tracks(fields, track, pts, np.full((n, 3), np.nan), np.zeros(n), np.arange(n))
    return Labelling(joined, ("A", "B", "C", "D", "M1", "M2"), True, (4, 5), (), 1.0)


def test_two_pieces_past_two_partners_ends_join_them_when_they_keep_their_length():
    # lowcost seed 373: RTIB and RANK seen again by two cameras after the rest of the leg
    # left; nothing named beside them, only their 210 mm length says which they are
    xyz = rigid_body(seed=7, noise_mm=0.2)
    got = join_gap_pieces(_ends(xyz, 0.0), TrackingParams())
    assert got.unlabelled == ()
    for name, m in (("A", 0), ("C", 2)):
        rows = got.tracks.track == got.labels.index(name)
        assert np.isin(np.arange(165, 200), got.tracks.field[rows]).all()
        err = np.linalg.norm(got.tracks.xyz_mm[rows] - xyz[m, got.tracks.field[rows]], axis=1)
        assert err.max() < 2.0
    # 55 mm apart, A-C's 80 less 25 (no pair of the body's is nearer than 70): not a
    # pair; C's piece, on C's path, takes C's name by its path alone, A's (25 mm off A's
    # path) none
    got = join_gap_pieces(_ends(xyz, -25.0), TrackingParams())
    assert got.labels == ("A", "B", "C", "D", "M1")
    assert np.array_equal(np.unique(got.tracks.field[got.tracks.track == 4]), np.arange(160, 200))
    rows = got.tracks.track == 2
    err = np.linalg.norm(got.tracks.xyz_mm[rows] - xyz[2, got.tracks.field[rows]], axis=1)
    assert err.max() < 2.0


def _segment_on_rays(xyz: np.ndarray, seed: int, markers=(1, 2, 3)) -> object:
    """One camera 3 m from the body sees ``markers`` through the gap, with two noise
    blobs a field anywhere."""
    target = xyz[3, GAP].mean(axis=0)
    dlts = _look_at(target + [2500.0, 1500.0, 600.0], target)[None]
    fields = np.arange(GAP.start, GAP.stop)
    rng = np.random.default_rng(seed)
    uv = [project_rows(dlts, np.zeros(fields.size, dtype=int), xyz[m, GAP]) for m in markers]
    uv = np.concatenate(uv) + rng.normal(0, 0.05, (len(markers) * fields.size, 2))
    noise = rng.uniform([0, 0], [640, 480], (2 * fields.size, 2))
    f = np.r_[np.tile(fields, len(markers)), np.repeat(fields, 2)]
    return spare_blobs(f, np.zeros(f.size), np.r_[uv, noise], dlts)


def _dense(tracks) -> np.ndarray:
    dense = np.full((tracks.n_tracks, int(tracks.field.max()) + 1, 3), np.nan)
    meas = tracks.status == MEASURED
    dense[tracks.track[meas], tracks.field[meas]] = tracks.xyz_mm[meas]
    return dense


def test_a_segment_one_camera_sees_is_placed_on_its_rays_together():
    xyz = rigid_body(seed=4, noise_mm=0.2)
    # three of the four markers hidden for 0.6 s, each on its ray in one camera
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    got = joint_ray_fill(dense, 3, GAP.start, GAP.stop, _segment_on_rays(xyz, 4), TrackingParams())
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.8 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0
    assert np.all(got.sd_mm[placed] <= TrackingParams().ray_length_max_error_mm)


def test_a_segment_on_rays_with_a_wrong_blob_is_not_placed():
    xyz = rigid_body(seed=6, noise_mm=0.2)
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    wrong = xyz.copy()
    wrong[3, GAP] += [0.0, 0.0, 25.0]  # the target's blob is another marker's, 25 mm off
    got = joint_ray_fill(
        dense, 3, GAP.start, GAP.stop, _segment_on_rays(wrong, 6), TrackingParams()
    )
    if got is not None:
        placed = np.isfinite(got.sd_mm)
        err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
        assert err.size <= 5 or np.sqrt(np.mean(err**2)) < 3.0


def test_a_marker_one_camera_sees_alone_is_placed_at_the_spline_s_distance():
    xyz = rigid_body(seed=7, noise_mm=0.2)
    # the whole body but marker 0 hidden: no length fixes the depth, the spline does
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    got = depth_ray_fill(dense, 3, GAP.start, GAP.stop, _segment_on_rays(xyz, 7, (3,)), PARAMS)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.9 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < max(2.0 * got.sd_mm[placed][0], 1.0)
    assert got.sd_mm[placed][0] <= PARAMS.ray_depth_max_error_mm


def test_a_marker_bobbing_along_the_camera_s_sight_is_not_placed_by_depth():
    xyz = rigid_body(seed=8, noise_mm=0.2)
    spare = _segment_on_rays(xyz, 8, (3,))
    sight = xyz[3, GAP].mean(axis=0) - spare.centres[0]
    sight /= np.linalg.norm(sight)
    # towards and away from the camera, 30 mm, twice per gap's length
    xyz[3] += 30.0 * np.sin(np.arange(xyz.shape[1]) * 4 * np.pi / 60)[:, None] * sight
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    spare = _segment_on_rays(xyz, 8, (3,))
    assert depth_ray_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS) is None


def test_a_walk_unbroken_from_its_side_settles_a_field_the_other_walk_left():
    # forward picks at offsets 0, 1, 2, then 9 after a hole of six fields; backward
    # (from offset 12) picks 11, 10 and, far from its side, 1
    fwd = {0: 0, 1: 0, 2: 1, 9: 0}
    bwd = {11: 0, 10: 0, 1: 1}
    near_f, near_b = connected_picks(fwd, -1, 3), connected_picks(bwd, 12, 3)
    assert near_f == {0, 1, 2} and near_b == {11, 10}
    got = {k: agreed_pick(fwd.get(k), bwd.get(k), k in near_f, k in near_b) for k in range(12)}
    # both walks' or one unbroken walk's where the other took none; never a field the
    # walks disagree on, nor one only a broken walk reached
    assert got == {0: 0, 1: None, 2: 1, 9: None, 10: 0, 11: 0} | {k: None for k in range(3, 9)}


def test_blob_paths_from_two_sides_part_when_one_end_is_another_marker_s():
    xyz = rigid_body(seed=4, noise_mm=0.2)
    spare = _segment_on_rays(xyz, 4, (2, 3))
    run = slice(GAP.start + 20, GAP.start + 25)
    target = xyz[3].copy()
    target[run] = np.nan
    assert not parted(target, run.start, run.stop, spare, PARAMS)
    # the samples after the run are marker 2's: its blobs lead back to them
    target[run.stop :] = xyz[2, run.stop :]
    assert parted(target, run.start, run.stop, spare, PARAMS)


def _two_cameras(xyz: np.ndarray, sub: slice, seed: int) -> object:
    """Camera 0 looking along marker 3 -> 0 sees marker 0 through GAP, camera 1 sees
    marker 3 in ``sub`` only; two noise blobs a field in each."""
    target = xyz[0, GAP].mean(axis=0)
    toward = np.mean(xyz[0, GAP] - xyz[3, GAP], axis=0)
    toward = 3000.0 * toward / np.linalg.norm(toward)
    dlts = np.stack(
        [
            _look_at(target + toward + [0, 300, 0], target),
            _look_at(target + [0, 3000.0, 500], target),
        ]
    )
    rng = np.random.default_rng(seed)
    parts = []
    for cam, marker, s in ((0, 0, GAP), (1, 3, sub)):
        fields = np.arange(s.start, s.stop)
        uv = project_rows(dlts, np.full(fields.size, cam), xyz[marker, s])
        noise = rng.uniform([0, 0], [640, 480], (2 * fields.size, 2))
        f = np.r_[fields, np.repeat(fields, 2)]
        parts.append((f, np.full(f.size, cam), np.r_[uv + rng.normal(0, 0.05, uv.shape), noise]))
    f, c, uv = (np.concatenate(x) for x in zip(*parts, strict=True))
    return spare_blobs(f, c, uv, dlts)


def _toe_and_heel(seed: int, sub: slice) -> np.ndarray:
    """:func:`rigid_body` with marker 0 swinging about marker 3 (a toe about the heel:
    their length holds, marker 0's to 1 and 2 do not) and the whole body bobbing along
    camera 0's sight (of :func:`_two_cameras`), not camera 1's: no spline of marker 0's
    distance from camera 0 bridges the gap."""
    xyz = rigid_body(seed=seed, noise_mm=0.2)
    n = xyz.shape[1]
    arm = xyz[0] - xyz[3]
    axis = np.cross(arm, xyz[1] + xyz[2] - 2 * xyz[3])
    angle = 0.4 * np.sin(np.arange(n) * 2 * np.pi / 50)
    swing = Rotation.from_rotvec(axis / np.linalg.norm(axis, axis=1)[:, None] * angle[:, None])
    xyz[0] = xyz[3] + swing.apply(arm)
    sight = xyz[0, GAP].mean(axis=0) - _two_cameras(xyz, sub, seed).centres
    sight /= np.linalg.norm(sight, axis=1)[:, None]
    bob = sight[0] - (sight[0] @ sight[1]) * sight[1]
    return xyz + 30.0 * np.sin(np.arange(n) * 2 * np.pi / 40)[:, None] * bob / np.linalg.norm(bob)


def test_a_marker_is_placed_by_a_partner_its_own_gap_filled_later():
    # marker 0 (the first track, filled first) on one camera's rays through the gap;
    # marker 3, its only partner, hidden for 0.2 s in it and seen by another camera,
    # placed there by its lengths to markers 1 and 2: only once it is placed can its
    # length place marker 0
    sub = slice(GAP.start + 20, GAP.start + 40)
    xyz = _toe_and_heel(9, sub)
    tracks = _tracks_of(xyz, {0: GAP, 3: sub})
    out, fills = fill_gaps_logged(tracks, PARAMS, _two_cameras(xyz, sub, 9))
    rows = (out.track == 0) & (out.field >= sub.start) & (out.field < sub.stop)
    assert rows.sum() == sub.stop - sub.start
    err = np.linalg.norm(out.xyz_mm[rows] - xyz[0, out.field[rows]], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0
    for g in fills:
        if g.track == 0 and sub.start <= g.first_field < sub.stop:
            r = (out.track == 0) & (out.field >= g.first_field)
            r &= out.field < g.first_field + g.n_fields
            e = np.linalg.norm(out.xyz_mm[r] - xyz[0, out.field[r]], axis=1)
            assert np.sqrt(np.mean(e**2)) < max(g.expected_error_mm, 1.0) + 0.5


def _hinged_foot(n: int = 300) -> np.ndarray:
    """Markers 0-3 (4, n, 3): 1, 2 and 3 one rigid segment moving along X; 0 on a hinge
    about the axis through 3 and 2 (lab Y), so its length to 1 changes (a shank marker
    seen with the foot)."""
    t = np.arange(n) / 100.0
    move = np.stack([300 * t, 50 * np.sin(t), 900 + 0 * t], 1)
    hinge = Rotation.from_rotvec(np.outer(0.8 * np.sin(3 * t), [0.0, 1.0, 0.0]))
    return np.stack(
        [
            hinge.apply([60.0, -30.0, 90.0]) + move,
            move + [80.0, 0.0, 20.0],
            move + [0.0, -70.0, 0.0],
            move,
        ]
    )


def _merged_and_own(xyz: np.ndarray, run: slice, seed: int) -> object:
    """Camera 0, looking along marker 2 -> 3, sees one blob where their images merge,
    in ``run``; camera 1 sees markers 1 and 3 in GAP and 2 in ``run``; two noise blobs
    a field in each."""
    target = xyz[3, GAP].mean(axis=0)
    dlts = np.stack(
        [
            _look_at(target + [0.0, 3000.0, 40.0], target),
            _look_at(target + [2500, 1500, 600], target),
        ]
    )
    rng = np.random.default_rng(seed)
    parts = [(0, run, (xyz[2] + xyz[3]) / 2), (1, GAP, xyz[1]), (1, GAP, xyz[3]), (1, run, xyz[2])]
    field, cam, uv = [], [], []
    for c, span, pts in parts:
        f = np.arange(span.start, span.stop)
        field, cam = [*field, f], [*cam, np.full(f.size, c)]
        uv.append(project_rows(dlts, cam[-1], pts[f]) + rng.normal(0, 0.05, (f.size, 2)))
    f = np.repeat(np.arange(xyz.shape[1]), 4)
    noise = rng.uniform([0, 0], [640, 480], (f.size, 2))
    return spare_blobs(
        np.concatenate([*field, f]),
        np.concatenate([*cam, np.tile([0, 0, 1, 1], xyz.shape[1])]),
        np.concatenate([*uv, noise]),
        dlts,
    )


def test_a_segment_on_rays_takes_each_marker_s_own_blob_and_a_track_starting_after():
    # the foot of a lab of four cameras in swing: ankle (3) and toe (1) on one camera's
    # rays, the heel (2) too, its track starting only after the gap (seen by one camera
    # before), and a second camera whose one blob is heel and ankle merged; only the
    # shank marker (0), on a hinge, measured. The three lengths among the foot's rays
    # fix it; the merged blob's ray is both markers' and neither's own.
    xyz = _hinged_foot()
    dense = xyz.copy()
    dense[[1, 3], GAP] = np.nan
    dense[2, : GAP.stop + 10] = np.nan
    spare = _merged_and_own(xyz, slice(0, GAP.stop + 10), 7)
    got = joint_ray_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.8 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0


#: The gap [LO, HI) of a marker walking along y that one camera sees through it, the
#: depth between its ray's two roots for a partner 400 mm away, and that length.
LO, HI, FAR_MM, LENGTH_MM = 80, 140, 80.0, 400.0


def _walk_seen_by_one_camera(n: int = 200) -> tuple[np.ndarray, ...]:
    """A marker's path along y, the camera's DLT, and per field the unit sight line and
    the horizontal unit vector across it."""
    t = np.arange(n)
    xyz = np.stack([0 * t, 10.0 * t - 1000, 900 + 0 * t], 1)
    centre = np.array([3000.0, 0, 1500])
    dlts = _look_at(centre, np.array([0.0, 0, 900]))[None]
    d = (xyz - centre) / np.linalg.norm(xyz - centre, axis=1)[:, None]
    side = np.cross(d, [0.0, 0, 1])
    side /= np.linalg.norm(side, axis=1)[:, None]
    return xyz, dlts, d, side


def _chain_fill_with_partners(
    xyz: np.ndarray, dlts: np.ndarray, d: np.ndarray, side: np.ndarray, third: np.ndarray
) -> tuple[object, np.ndarray, np.ndarray]:
    """Chain-fill marker 0 through [LO, HI) on the camera's rays, beside marker 1 (rigid
    with it, meeting its ray at two roots FAR_MM apart) and ``third``: the fill, which
    fields it placed, and their errors against ``xyz``."""
    dense = np.stack([xyz, xyz + 0.5 * FAR_MM * d + 150.0 * np.cross(d, side), third])
    dense[0, LO:HI] = np.nan
    f = np.arange(LO, HI)
    uv = project_rows(dlts, np.zeros(f.size, dtype=int), xyz[LO:HI])
    got = chain_fill(dense, 0, LO, HI, spare_blobs(f, np.zeros(f.size), uv, dlts), PARAMS)
    placed = np.isfinite(got.sd_mm)
    return got, placed, np.linalg.norm(got.xyz_mm[placed] - xyz[LO:HI][placed], axis=1)


def test_a_partner_s_drifting_length_does_not_place_the_ray_s_other_root():
    # marker 0 walks along y; one camera sees it through its gap [80, 140). Marker 1,
    # rigid with it, meets its ray at two depths 80 mm apart (0 and its other root);
    # marker 2's length fits both until field 100, then drifts (a thigh marker's to the
    # shank across the knee) to fit only the other root until 126 (modern 3 seed 332
    # RTHI 465-517: 87-262 mm off, expecting 2.47)
    far, length = FAR_MM, LENGTH_MM
    xyz, dlts, d, side = _walk_seen_by_one_camera()
    other = xyz + far * d
    both = xyz + length * (0.1 * d + np.sqrt(0.99) * side)  # 0.1 = far / (2 length)
    t = np.arange(len(xyz))
    w = np.clip((t - 100) / 3.0, 0, 1) * np.clip((126 - t) / 3.0, 0, 1)
    drift = both * (1 - w[:, None]) + (other + length * side) * w[:, None]
    got, placed, err = _chain_fill_with_partners(xyz, dlts, d, side, drift)
    assert placed.sum() >= 30 and np.all(err <= 2.0 * got.sd_mm[placed])


def test_a_length_held_only_over_a_phase_is_no_partner_s():
    # marker 0 walks along y; one camera sees it through its gap [80, 140); marker 1,
    # rigid with it, meets its ray at two depths 80 mm apart. Marker 2 is seen with it
    # only in fields 150-199 (36 % of its fields), where their distance held (a thigh
    # marker and the sacrum while the hip stays still); in the gap it fits only the other
    # root (modern 3 seed 332 RTHI 452-466 with SACR: 83 mm off, expecting 1.7)
    lo, hi = LO, HI
    xyz, dlts, d, side = _walk_seen_by_one_camera()
    phase = xyz + LENGTH_MM * side
    phase[lo:hi] = xyz[lo:hi] + FAR_MM * d[lo:hi] + LENGTH_MM * side[lo:hi]
    phase[:lo] = phase[hi:150] = np.nan
    got, placed, err = _chain_fill_with_partners(xyz, dlts, d, side, phase)
    assert placed.sum() >= 30 and np.all(err <= 2.0 * got.sd_mm[placed]), err.max()
    assert 2 not in got.partners
