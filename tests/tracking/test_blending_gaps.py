import numpy as np

from kisscal.tracking import (
    FILLED,
    MEASURED,
    TrackingParams,
    blend_tracks,
    clean_up,
    smooth_tracks,
)
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.tracks import make_tracks


def _tracks(pieces):
    field, track, xyz = [], [], []
    for k, (f, p) in enumerate(pieces):
        field.append(f)
        track.append(np.full(f.size, k))
        xyz.append(p)
    n = sum(f.size for f, _ in pieces)
    return make_tracks(
        np.concatenate(field),
        np.concatenate(track),
        np.concatenate(xyz),
        np.full((n, 3), np.nan),
        np.zeros(n),
        np.arange(n),
    )


def _curve(f):
    f = np.asarray(f, dtype=float)
    return np.stack([15.0 * f, 100 * np.sin(f / 10), 800 + 40 * np.cos(f / 7)], axis=1)


def test_blending_joins_pieces_two_fields_apart_and_continuous():
    a = np.arange(0, 30)
    b = np.arange(33, 60)  # fields 30-32 missing
    far = np.arange(33, 60)
    tracks = _tracks([(a, _curve(a)), (b, _curve(b)), (far, _curve(far) + np.array([0, 300, 0]))])
    out = blend_tracks(tracks, TrackingParams(blend_gap_fields=3))
    assert out.n_tracks == 2
    joined = out.track[out.field == 0][0]
    assert set(out.field[out.track == joined]) == set(a) | set(b)


def test_blending_refuses_gaps_longer_than_allowed():
    a = np.arange(0, 30)
    b = np.arange(35, 60)
    tracks = _tracks([(a, _curve(a)), (b, _curve(b))])
    assert blend_tracks(tracks, TrackingParams(blend_gap_fields=2)).n_tracks == 2


def test_clean_up_removes_short_tracks():
    a = np.arange(0, 30)
    g = np.arange(5, 9)
    tracks = _tracks([(a, _curve(a)), (g, _curve(g) + 500)])
    out = clean_up(tracks, TrackingParams(min_track_length=10))
    assert out.n_tracks == 1 and out.field.size == 30


def test_fill_gaps_is_accurate_on_smooth_motion_and_marks_filled():
    f = np.r_[np.arange(0, 40), np.arange(48, 80)]
    tracks = _tracks([(f, _curve(f))])
    out, _ = fill_gaps_logged(tracks, TrackingParams(max_fill_gap_fields=10))
    filled = out.status == FILLED
    assert out.field[filled].tolist() == list(range(40, 48))
    err = np.linalg.norm(out.xyz_mm[filled] - _curve(out.field[filled]), axis=1)
    assert err.max() < 2.0
    assert (out.status == MEASURED).sum() == f.size


def test_fill_gaps_leaves_long_gaps():
    f = np.r_[np.arange(0, 40), np.arange(80, 120)]
    out, _ = fill_gaps_logged(_tracks([(f, _curve(f))]), TrackingParams(max_fill_gap_fields=25))
    assert not (out.status == FILLED).any()


def test_gcv_smoothing_reduces_noise_error():
    rng = np.random.default_rng(0)
    f = np.arange(200)
    truth = _curve(f)
    tracks = _tracks([(f, truth + rng.normal(0, 1.0, truth.shape))])
    smooth = smooth_tracks(tracks)
    before = np.sqrt(np.mean(np.sum((tracks.xyz_mm - truth) ** 2, axis=1)))
    after = np.sqrt(np.mean(np.sum((smooth.xyz_mm - truth) ** 2, axis=1)))
    assert after < 0.7 * before


def test_a_neighbour_that_three_samples_a_side_would_join_is_refused():
    """Two markers 60 mm apart on one bar moving 20 mm per field: the front one is seen
    from field 23 on, just after the rear one vanished at 19. A cubic through three
    samples a side fits the wrong join within the 3 mm tolerance (2.4 mm); through five
    a side it misses by 4.6 mm, many times the pieces' own noise (0.05 mm): no join. The
    rear marker's own return at 23 is joined."""
    rng = np.random.default_rng(3)
    early, late = np.arange(0, 20), np.arange(23, 43)

    def bar(f, ahead_mm):
        xyz = np.zeros((f.size, 3))
        xyz[:, 0] = 20.0 * f + ahead_mm
        return xyz + rng.normal(0.0, 0.05, xyz.shape)

    params = TrackingParams()
    for ahead_mm, joined in ((60.0, False), (0.0, True)):
        tracks = _tracks([(early, bar(early, 0.0)), (late, bar(late, ahead_mm))])
        assert (blend_tracks(tracks, params).n_tracks == 1) == joined


def test_a_join_another_marker_contests_in_its_gap_is_refused():
    """Two markers 20 mm apart on a push rim (radius 300 mm) turning 30 mm per field: the
    front one is lost after field 9, the rear one is seen at 8-11 (a piece too short to
    blend), lost at 12 and seen again from 13. Joining the front marker's piece to the
    rear one's return passes the continuity tests (the rim's path is one smooth curve);
    the rear marker's samples at 10 and 11, on the return's path and in a piece that ran
    beside the front one, refuse it. The front marker's own return is joined."""
    rng = np.random.default_rng(1)
    lag = 2 * np.arcsin(20.0 / 2 / 300.0)

    def rim(f, phase):
        t = 0.1 * f + phase
        xyz = np.stack([300 * np.cos(t), 300 * np.sin(t), np.full(f.size, 800.0)], axis=1)
        return xyz + rng.normal(0.0, 0.1, xyz.shape)

    front, rear, back = np.arange(0, 10), np.arange(8, 12), np.arange(13, 40)
    params = TrackingParams()
    for phase, joined in ((lag, False), (0.0, True)):
        tracks = _tracks(
            [(front, rim(front, 0.0)), (rear, rim(rear, lag)), (back, rim(back, phase))]
        )
        out = blend_tracks(tracks, params)
        first = out.track[out.field == 0][0]
        assert (39 in out.field[out.track == first]) == joined


def test_a_join_whose_end_another_piece_explains_better_is_refused():
    """Two LEDs 5 mm apart along a club moving 30 mm per field: the first is tracked at
    0-9 and, from 10, seen in a piece too short to blend (10-12); the second appears at
    10. One cubic takes the first piece on to the second LED (a 5 mm step in 30), but the
    first LED's sample at 10 lies on the first piece's extrapolation: refused. Without that
    sample the join is made."""

    def club(f, offset):
        f = np.asarray(f, dtype=float)
        xyz = np.stack([30.0 * f + offset, 2.0 * f, 0.05 * f**2], axis=1)
        return xyz + np.random.default_rng(2).normal(0.0, 0.05, xyz.shape)

    first, again, second = np.arange(0, 10), np.arange(10, 13), np.arange(10, 30)
    for seen, joined in ((True, False), (False, True)):
        pieces = [(first, club(first, 0.0)), (second, club(second, 5.0))]
        if seen:
            pieces.append((again, club(again, 0.0)))
        out = blend_tracks(_tracks(pieces), TrackingParams())
        start = out.track[out.field == 0][0]
        assert (29 in out.field[out.track == start]) == joined


def test_rival_joins_are_chosen_together_not_refused_one_at_a_time():
    """Two markers 30 mm apart on a foot both shift 40 mm back (a smooth step over fields
    8-13) while unseen at 10 and 11. Each one's return lies farther from its own piece's
    extrapolation than the other's return does, by a few mm: judged one join at a time,
    each true join is refused for the rival's nearer sample and the crossed join is made
    (or one marker left unjoined). Chosen together, both true joins are made and none
    crossed."""

    def foot(f, x0):
        u = np.clip((np.asarray(f, dtype=float) - 8.0) / 5.0, 0.0, 1.0)
        xyz = np.zeros((f.size, 3))
        xyz[:, 0] = x0 - 40.0 * (3 * u**2 - 2 * u**3)
        xyz[:, 2] = 800.0
        return xyz + rng.normal(0.0, 0.3, xyz.shape)

    rng = np.random.default_rng(1)
    early, late = np.arange(0, 10), np.arange(12, 30)
    pieces = [(early, foot(early, 0.0)), (early, foot(early, 30.0))]
    pieces += [(late, foot(late, 0.0)), (late, foot(late, 30.0))]
    out = blend_tracks(_tracks(pieces), TrackingParams())
    assert out.n_tracks == 2
    for x0 in (0.0, 30.0):
        first = out.track[(out.field == 0) & (np.abs(out.xyz_mm[:, 0] - x0) < 5.0)][0]
        mine = out.track == first
        assert 29 in out.field[mine]
        assert np.all(np.abs(out.xyz_mm[mine & (out.field >= 12), 0] - (x0 - 40.0)) < 5.0)


def test_a_track_is_certain_of_its_point_when_rivals_lie_beyond_its_own_misses():
    """A track predicting within 0.3 mm is sure of its point when the next lies 5 mm away
    (4 times 0.3 is less), not when its misses are 2 mm, nor when another track predicted
    its point nearer."""
    from kisscal.tracking.association import certain_rows

    pred = np.array([[0.0, 0.0, 0.0]])
    points = np.array([[0.2, 0.0, 0.0], [5.0, 0.0, 0.0]])
    found = points[:1]
    for spread, sure in ((0.3, True), (2.0, False)):
        got = certain_rows(pred, found, points, np.array([spread]), 4.0, pred)
        assert bool(got[0]) == sure
    other = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]])
    assert not certain_rows(pred, found, points, np.array([0.3]), 4.0, other)[0]


def test_a_point_a_track_left_without_one_predicted_within_reach_stays_a_doubt():
    """A cluster's LED vanishes: its track, left without a point, predicted the point a
    neighbour's track took within that track's reach (4 times its 3 mm misses: 12 mm),
    so the neighbour is not sure of it; a lost track 20 mm off leaves it sure."""
    from kisscal.tracking.association import certain_rows

    pred = np.array([[0.0, 0.0, 0.0]])
    points = np.array([[1.0, 0.0, 0.0], [50.0, 0.0, 0.0]])
    found, spread = points[:1], np.array([3.0])
    assert certain_rows(pred, found, points, spread, 4.0, pred)[0]
    for lost_at, sure in ((8.0, False), (20.0, True)):
        lost = np.array([[lost_at, 0.0, 0.0]])
        assert bool(certain_rows(pred, found, points, spread, 4.0, pred, lost)[0]) == sure


def _turning_pair(turn: float, steps: int = 4):
    """Two markers 50 mm apart on a body that turns ``turn`` (radians) within ``steps``
    fields from field 30, both seen only as one-sample pieces while it turns: pieces
    (fields, positions, true marker) before, one per turning field, and after."""
    f = np.arange(64)
    angle = np.clip((f - 29) / steps, 0, 1) * turn
    centre = np.stack([3.0 * f, 2.0 * f, 900.0 + 0 * f], axis=1)
    before, after = f < 30, f >= 29 + steps
    pieces = []
    for k, phase in enumerate((0.0, np.pi)):
        x = centre + 25.0 * np.stack([np.cos(angle + phase), np.sin(angle + phase), 0 * f], 1)
        pieces += [(f[before], x[before], k), (f[after], x[after], k)]
        pieces += [(f[g : g + 1], x[g : g + 1], k) for g in np.flatnonzero(~before & ~after)]
    return pieces


def _markers_per_track(pieces, out):
    """How many true markers each output track holds (matched by field and position)."""
    key = {
        (int(g), *np.round(p, 6).tolist()): k
        for f, x, k in pieces
        for g, p in zip(f, x, strict=True)
    }
    per_track = []
    for t in range(out.n_tracks):
        rows = np.flatnonzero(out.track == t)
        per_track.append(
            len({key[(int(out.field[r]), *np.round(out.xyz_mm[r], 6).tolist())] for r in rows})
        )
    return per_track


def test_blending_judges_a_join_through_the_one_sample_pieces_in_its_gap():
    # A half turn within the gap brings each marker to where the other was: end to end,
    # each piece's end meets the other marker's start (the crossed join fits best); the
    # one-sample pieces seen while it turns show the paths do not continue that way.
    pieces = _turning_pair(np.pi)
    out = blend_tracks(_tracks([(f, x) for f, x, _ in pieces]), TrackingParams())
    assert max(_markers_per_track(pieces, out)) == 1


def test_blending_still_joins_across_one_sample_pieces_that_continue_the_path():
    pieces = _turning_pair(0.2 * np.pi)
    out = blend_tracks(_tracks([(f, x) for f, x, _ in pieces]), TrackingParams())
    # each marker's pieces, the one-sample ones in the gap too, make one track
    assert out.n_tracks == 2 and max(_markers_per_track(pieces, out)) == 1


def _swing(f, jerk: float, lead: float = 0.0):
    """A club head at 130 mm a field whose speed peaks at field 10 (``jerk`` mm/field³); a
    second LED ``lead`` fields ahead on the same path (0.14: 18.5 mm)."""
    t = np.asarray(f, dtype=float) + lead
    x = 130.0 * t - jerk * (t - 10.0) ** 3 / 6.0
    return np.stack([x, 0.3 * x, 500.0 + 0.0 * t], axis=1)


def test_a_join_neither_extrapolation_tells_from_a_neighbour_is_refused():
    """Two LEDs 18.5 mm apart along a club's path: the first is tracked at 0-9, then seen
    only as one-sample pieces; the second is seen as one-sample pieces up to 10 and tracked
    from 11 (or, the other way round, the first LED is tracked again from 11). One cubic
    takes the first piece on to either LED's later piece. At jerk 6 the extrapolations
    across the gap miss by more (34 mm) than the LEDs are apart, at both ends: which LED
    they meet nearer is chance, and no join is made (one was, to the second LED). At jerk 1
    they tell the LEDs apart: the first LED's own later piece is joined, the other's not."""
    first, later = np.arange(0, 10), np.arange(11, 25)
    for jerk in (1.0, 6.0):
        for same_led in (True, False):
            ahead = {True: (0.0, 0.14), False: (0.14, 0.0)}[same_led]
            pieces = [(first, _swing(first, jerk)), (later, _swing(later, jerk, ahead[0]))]
            # the LED not tracked after the gap, seen alone; the second LED before it
            pieces += [(np.array([g]), _swing([g], jerk, ahead[1])) for g in range(10, 25)]
            pieces += [(np.array([g]), _swing([g], jerk, 0.14)) for g in range(0, 10)]
            if not same_led:
                pieces.append((np.array([10]), _swing([10], jerk, 0.14)))
            out = blend_tracks(_tracks(pieces), TrackingParams())
            start = out.track[
                (out.field == 0) & (np.abs(out.xyz_mm[:, 0] - _swing([0], jerk)[0, 0]) < 1e-6)
            ]
            joined = np.isin(later, out.field[out.track == start[0]]).all()
            assert joined == (same_led and jerk == 1.0), (jerk, same_led)


def test_a_rival_whose_other_end_misses_farther_does_not_contest_the_join():
    """A heel and an ankle 80 mm apart on a foot whose acceleration changes fast (heel
    strike, lowcost 4 cameras seed 428): the heel is lost at 10-13, the ankle's earlier
    piece ended at 2. The heel's forward guess across the gap lies nearer the ankle's
    return than its own, its own return's backward guess nearer its end than the
    ankle's: the two ends disagree, and the heel's own return (one cubic with it) is
    joined, never the ankle's (main took the ankle's in 4 of these 6 noise draws)."""

    def foot(f, offset, rng):
        f = np.asarray(f, dtype=float)
        xyz = np.stack([-0.5 * f**2 + 0.1 * f**3 + offset, 2.0 * f, 800.0 + 0.0 * f], axis=1)
        return xyz + rng.normal(0.0, 1.0, xyz.shape)

    early, late = np.arange(0, 10), np.arange(14, 30)
    for seed in range(6):
        rng = np.random.default_rng(seed)
        pieces = [(early, foot(early, 0.0, rng)), (late, foot(late, 0.0, rng))]
        pieces += [(np.arange(0, 3), foot(np.arange(0, 3), -80.0, rng))]
        pieces += [(late, foot(late, -80.0, rng))]
        out = blend_tracks(_tracks(pieces), TrackingParams())
        heel = out.track == out.track[(out.field == 9)][0]
        back = out.xyz_mm[heel & (out.field >= 14), 0]
        assert back.size == late.size, seed
        assert np.all(np.abs(back - foot(late, 0.0, rng)[:, 0]) < 10.0), seed  # not 80 off
