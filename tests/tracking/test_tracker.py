import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.tracking import MEASURED, PREDICTED, TrackingParams, associate, track_points
from kisscal.tracking.association import ambiguous_rows, lookahead_cost
from kisscal.tracking.tracker import split_ambiguous_first_steps, split_short_reacquisitions
from kisscal.tracking.tracks import make_tracks


def _cloud(paths, seed=0, noise_mm=1.0, missing=()):
    """Points of several (n_fields, 3) paths; ``missing`` = (path, field) pairs left out."""
    rng = np.random.default_rng(seed)
    field, xyz, who = [], [], []
    for k, path in enumerate(paths):
        for f in range(path.shape[0]):
            if (k, f) in missing:
                continue
            field.append(f)
            xyz.append(path[f] + rng.normal(0, noise_mm, 3))
            who.append(k)
    return np.array(field), np.array(xyz), np.array(who)


def _identities(tracks, who):
    """Set of true paths seen in each track's measured samples."""
    out = []
    for t in range(tracks.n_tracks):
        rows = (tracks.track == t) & (tracks.status == MEASURED)
        out.append(set(who[tracks.point[rows]].tolist()))
    return out


def test_associate_is_one_to_one_and_globally_best():
    # Greedy nearest-first would give point 0 to track 0 and leave track 1 without a point.
    predicted = np.array([[0.0, 0, 0], [8.0, 0, 0]])
    half = np.full((2, 3), 10.0)
    points = np.array([[5.0, 0, 0], [-4.0, 0, 0]])
    rows, cols = associate(predicted, half, points)
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 1), (1, 0)]


def test_associate_respects_box_gate_per_axis():
    rows, _ = associate(np.zeros((1, 3)), np.array([[10.0, 10.0, 2.0]]), np.array([[0, 0, 3.0]]))
    assert rows.size == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("gap_mm", [25.0, 12.0])
def test_crossing_markers_within_30_mm_keep_identities(seed, gap_mm):
    f = np.arange(120.0)[:, None]
    # A fast marker crosses the path of a slow one gap_mm above it, at different speeds.
    a = np.hstack([-700 + 12.0 * f, 0 * f, 1000 + 0 * f])
    b = np.hstack([0 * f, -420 + 7.0 * f, 1000 - gap_mm + 0 * f])
    # And a marker overtakes another at gap_mm lateral distance.
    c = np.hstack([-300 + 9.0 * f, 500 + 0 * f, 600 + 0 * f])
    d = np.hstack([-50 + 5.0 * f, 500 + gap_mm + 0 * f, 600 + 0 * f])
    closest = min(np.linalg.norm(a - b, axis=1).min(), np.linalg.norm(c - d, axis=1).min())
    assert closest < 30.0
    field, xyz, who = _cloud([a, b, c, d], seed=seed)
    tracks = track_points(field, xyz, TrackingParams())
    ids = _identities(tracks, who)
    assert all(len(s) == 1 for s in ids)
    long = [s for t, s in enumerate(ids) if (tracks.track == t).sum() > 100]
    assert sorted(next(iter(s)) for s in long) == [0, 1, 2, 3]


def test_coasting_bridges_dropouts_with_predictions():
    f = np.arange(80.0)[:, None]
    path = np.hstack([10.0 * f, 200 + 30 * np.sin(f / 8), 900 + 0 * f])
    missing = {(0, 40), (0, 41), (0, 42)}
    field, xyz, _ = _cloud([path], missing=missing)
    tracks = track_points(field, xyz, TrackingParams())
    assert tracks.n_tracks == 1
    pred = tracks.field[tracks.status == PREDICTED]
    assert pred.tolist() == [40, 41, 42]
    err = np.linalg.norm(tracks.xyz_mm[tracks.status == PREDICTED] - path[40:43], axis=1)
    assert err.max() < 10.0


def test_track_ends_after_max_coasted_fields():
    f = np.arange(60.0)[:, None]
    path = np.hstack([8.0 * f, 0 * f, 0 * f])
    missing = {(0, k) for k in range(25, 35)}
    params = TrackingParams(max_coasted_fields=3)
    field, xyz, _ = _cloud([path], missing=missing)
    tracks = track_points(field, xyz, params)
    assert tracks.n_tracks == 2
    # Trailing predictions of the ended track are dropped.
    first = tracks.field[tracks.track == 0]
    assert first.max() == 24


def test_lookahead_prefers_the_continuation_that_continues():
    start = np.array([[0.0, 0, 0]])
    cands = np.array([[10.0, 0, 0], [3.0, 0, 0]])
    later = np.array([[20.0, 0, 0]])
    cost = lookahead_cost(start, cands, later, 10.0)
    assert cost[0, 0] < cost[0, 1]


def test_short_reacquisition_after_coasting_is_split_off():
    f = np.arange(50.0)[:, None]
    path = np.hstack([5.0 * f, 0 * f, 0 * f])
    field, xyz, _ = _cloud([path], missing={(0, k) for k in range(30, 50)})
    ghost_field = np.array([33])
    ghost = np.array([[5.0 * 33 + 8, 4.0, 0]])
    field = np.r_[field, ghost_field]
    xyz = np.r_[xyz, ghost]
    tracks = track_points(field, xyz, TrackingParams())
    # The ghost caught while coasting becomes a piece of its own; the track ends at 29.
    assert tracks.n_tracks == 2
    assert tracks.field[tracks.track == 0].max() == 29
    assert tracks.field[tracks.track == 1].tolist() == [33]
    again = split_short_reacquisitions(tracks, 3)
    assert again.field.size == tracks.field.size


@pytest.mark.parametrize(
    ("field", "xyz"),
    [
        (np.array([0, 1]), np.zeros((3, 3))),
        (np.array([0, -1]), np.zeros((2, 3))),
        (np.array([0, 1]), np.array([[0, 0, np.nan], [0, 0, 0]])),
    ],
)
def test_bad_points_raise(field, xyz):
    with pytest.raises(KisscalError):
        track_points(field, xyz, TrackingParams())


@pytest.mark.parametrize("n_init", [2, 5, 8, 12])
def test_any_initial_length_tracks_a_path_whole(n_init):
    """A longer initial track (more points before the filter starts) was a crash above 5:
    the tracker kept only the last five positions to fit the filter's first state to."""
    f = np.arange(120.0)[:, None]
    path = np.hstack([12.0 * f, 200 + 40 * np.sin(f / 9), 900 + 20 * np.cos(f / 7)])
    field, xyz, _ = _cloud([path])
    tracks = track_points(field, xyz, TrackingParams(min_initial_length=n_init))
    assert tracks.n_tracks == 1
    measured = tracks.status == MEASURED
    assert measured.sum() == 120
    filtered = np.isfinite(tracks.corrected_mm[:, 0])  # NaN until the filter starts
    assert np.flatnonzero(filtered)[0] == n_init - 1
    error = tracks.corrected_mm[filtered] - path[tracks.field[filtered].astype(int)]
    assert np.abs(error).max() < 6.0  # 1 mm noise per axis


def test_ambiguous_rows_mark_near_swaps_lost_and_left_points():
    """Two tracks and two points: a swap costing no more is ambiguous, one costing 2
    more is not; a track that lost a point it wanted nearly as much as its owner, and a
    track that left a free point almost as near as its own, are ambiguous."""
    inside = np.ones((2, 2), dtype=bool)
    rows, cols = np.array([0, 1]), np.array([0, 1])
    near = np.array([[0.1, 0.15], [0.15, 0.2]])
    far = np.array([[0.1, 1.1], [1.2, 0.2]])
    assert ambiguous_rows(near, inside, rows, cols, 0.5).tolist() == [True, True]
    assert ambiguous_rows(far, inside, rows, cols, 0.5).tolist() == [False, False]
    assert ambiguous_rows(near, inside, rows, cols, 0.0).tolist() == [False, False]
    # Track 1 lost point 0 to track 0 (0.3 against 0.1); point 1 is in no gate.
    lost = np.array([[0.1, 9.0], [0.3, 9.0]])
    gate = np.array([[True, False], [True, False]])
    zero = np.array([0])
    assert ambiguous_rows(lost, gate, zero, zero, 0.5).tolist() == [True, True]
    assert ambiguous_rows(lost, gate, zero, zero, 0.1).tolist() == [False, False]
    # Track 0 took point 0 (0.1) and left point 1 (0.4) free: ambiguous at 0.5.
    left = np.array([[0.1, 0.4], [9.0, 9.0]])
    gate = np.array([[True, True], [False, False]])
    assert ambiguous_rows(left, gate, zero, zero, 0.5).tolist() == [True, False]
    assert ambiguous_rows(left, gate, zero, zero, 0.2).tolist() == [False, False]


def _young_scene(fast_mm_per_field):
    """Four filtered markers (one of them at ``fast_mm_per_field``) and a marker A seen
    for three fields (10-12) that vanishes, with a marker B appearing 53 mm from A's path
    at field 13 (BTS.c3d's SCR1 and SCR2): paths, and the (path, field) pairs missing."""
    f = np.arange(30.0)[:, None]
    paths = [np.hstack([2.0 * f, 300.0 * k + 0 * f, 900 + 0 * f]) for k in range(3)]
    paths.append(np.hstack([fast_mm_per_field * f, -400 + 0 * f, 900 + 0 * f]))
    a = np.hstack([1000 + 1.5 * f, 1000 + 0 * f, 500 + 0 * f])
    b = a + [-29.0, -44.0, -23.0] + np.hstack([1.0 * (f - 13), 0 * f, 0 * f])
    paths += [a, b]
    missing = {(4, k) for k in range(30) if not 10 <= k <= 12}
    missing |= {(5, k) for k in range(13)}
    return paths, missing


@pytest.mark.parametrize("fast", [2.0, 40.0])
def test_young_track_does_not_take_a_marker_appearing_beside_it(fast):
    """A three-point track's gate is at least the Kalman gate of the trial's fastest
    filtered speed, not a fixed 60 mm: in a trial moving at most 2 or 40 mm/field, a
    marker that appears 53 mm from where a young one vanished starts its own track."""
    paths, missing = _young_scene(fast)
    field, xyz, who = _cloud(paths, noise_mm=0.2, missing=missing)
    tracks = track_points(field, xyz, TrackingParams())
    ids = _identities(tracks, who)
    assert {4} in ids and {5} in ids
    assert all(len(s) == 1 for s in ids)


def test_young_track_keeps_a_turning_marker_in_a_fast_trial():
    """When the trial's markers move fast (here 100 mm/field), a young track's gate stays
    wide enough for a marker of it to change its velocity by 40 mm in a field."""
    paths, missing = _young_scene(100.0)
    # Path 5 is marker A going on from field 13, 40 mm off its straight line.
    paths[5] = paths[4] + (np.arange(30.0) >= 13)[:, None] * np.array([-40.0, 0.0, 0.0])
    field, xyz, who = _cloud(paths, noise_mm=0.2, missing=missing)
    tracks = track_points(field, xyz, TrackingParams())
    ids = _identities(tracks, who)
    assert {4, 5} in ids  # one marker (path 5 continues path 4), one track


def test_a_short_pieces_guessed_first_step_is_split_off():
    """Two-point pieces: one whose second point had another point of its field almost as
    near its first (121 and 129 mm: which marker it took was a guess) loses its first
    point; one whose rival is three times as far keeps it, as does a Kalman-length piece."""
    xyz = np.array(
        [
            [0.0, 0.0, 0.0], [121.0, 0.0, 0.0], [0.0, 129.0, 0.0],  # guessed
            [1e3, 0.0, 0.0], [1121.0, 0.0, 0.0], [1e3, 363.0, 0.0],  # clear
        ]
    )  # fmt: skip
    field = np.array([0, 1, 1, 0, 1, 1])
    track = np.array([0, 0, 1, 2, 2, 3])
    n = field.size
    tracks = make_tracks(field, track, xyz, np.full((n, 3), np.nan), np.zeros(n), np.arange(n))
    params = TrackingParams()
    out = split_ambiguous_first_steps(tracks, params)
    assert out.n_tracks == 5
    alone = out.track[out.point == 0][0]
    assert np.sum(out.track == alone) == 1
    assert out.track[out.point == 3][0] == out.track[out.point == 4][0]
    assert split_ambiguous_first_steps(tracks, params.replace(min_initial_length=2)).n_tracks == 4


def test_a_step_after_a_guessed_first_step_is_judged_again():
    """A three-point piece whose two steps were each as near another point of their field
    (121 against 129 and 125 mm): the second was taken with the velocity of the guessed
    first, and is split off as well, leaving three pieces; a piece whose second step is
    clear (its rival three times as far) keeps it after losing its first point."""
    xyz = np.array(
        [
            [0.0, 0.0, 0.0], [121.0, 0.0, 0.0], [242.0, 0.0, 0.0],  # guessed twice
            [0.0, 129.0, 0.0], [121.0, 125.0, 0.0],  # their rivals
            [1e3, 0.0, 0.0], [1121.0, 0.0, 0.0], [1242.0, 0.0, 0.0],  # guessed once
            [1e3, 129.0, 0.0], [1121.0, 363.0, 0.0],  # their rivals
        ]
    )  # fmt: skip
    field = np.array([0, 1, 2, 1, 2, 0, 1, 2, 1, 2])
    track = np.array([0, 0, 0, 1, 2, 3, 3, 3, 4, 5])
    n = field.size
    tracks = make_tracks(field, track, xyz, np.full((n, 3), np.nan), np.zeros(n), np.arange(n))
    out = split_ambiguous_first_steps(tracks, TrackingParams())
    piece = {p: out.track[out.point == p][0] for p in range(n)}
    assert len({piece[0], piece[1], piece[2]}) == 3
    assert piece[5] != piece[6] == piece[7]


def test_a_short_pieces_first_step_with_a_rival_track_is_split_off():
    """A two-point piece whose second point lies almost as near another point of the
    first field (LEDs 7.6 mm apart on a golf club, both moving 9.7 mm a field, one hidden
    in the second: the hidden one's point is the nearer, 7.8 mm) loses its first point,
    however short the step, when the rival's track ended there (it found no point); one
    whose rival is four times as far keeps it, as does one whose rival went on."""
    xyz = np.array(
        [
            [0.0, 0.0, 0.0], [6.0, -5.0, 0.6], [-2.0, -5.0, -5.0],  # guessed
            [1e3, 0.0, 0.0], [1006.0, -5.0, 0.6], [1e3, -30.0, 0.0],  # clear
            [2e3, 0.0, 0.0], [2006.0, -5.0, 0.6], [1998.0, -5.0, -5.0], [1998.0, -5.0, -13.0],
        ]
    )  # fmt: skip
    field = np.array([0, 1, 0, 0, 1, 0, 0, 1, 0, 1])
    track = np.array([0, 0, 1, 2, 2, 3, 4, 4, 5, 5])
    n = field.size
    tracks = make_tracks(field, track, xyz, np.full((n, 3), np.nan), np.zeros(n), np.arange(n))
    out = split_ambiguous_first_steps(tracks, TrackingParams())
    assert out.track[out.point == 0][0] != out.track[out.point == 1][0]
    assert out.track[out.point == 3][0] == out.track[out.point == 4][0]
    assert out.track[out.point == 6][0] == out.track[out.point == 7][0]


@pytest.mark.parametrize("jerk_mm", [0.0, 5.0])
def test_continuation_tells_a_fast_marker_from_its_nearer_neighbour(jerk_mm):
    """Two markers of one fast limb 16 mm apart on a cubic path (third difference 6 *
    ``jerk_mm``): with a jerk the quadratic prediction misses the marker by 30 mm and its
    neighbour lies nearer; the field after shows which point continues the path."""
    from kisscal.tracking.association import continuation_doubts

    t = np.arange(5.0)[:, None]
    a = np.hstack([jerk_mm * t**3 + 40.0 * t, 2.0 * t**2, np.zeros_like(t)])
    b = a + np.array([-15.0, 5.0, 0.0])
    history = a[None, :3]
    pred = 3 * a[2] - 3 * a[1] + a[0]
    points, later = np.stack([a[3], b[3]]), np.stack([a[4], b[4]])
    # With the jerk, the one-field choice (the nearest point) is the neighbour's.
    nearest = np.argmin(np.linalg.norm(points - pred, axis=1))
    assert nearest == (1 if jerk_mm else 0)
    # Taking the neighbour is a doubt, taking the marker's own point is not.
    got = [continuation_doubts(history, p[None], points, later, 10.0)[0] for p in points]
    assert got == [False, True]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_hidden_markers_track_is_cut_where_it_takes_its_neighbours_point(seed):
    """Two markers 55 mm apart move 40 mm per field; at field 15 the limb jumps 40 mm
    sideways towards the first, which is hidden for three fields. Its track's prediction
    lies 15 mm from the second marker's point, the second's own track's 40 mm (inside
    its gate): the first track takes it, and nothing in the field says which marker
    vanished. The tracks are cut there, so that no piece holds both markers (blending
    judges the joins from both sides)."""
    f = np.arange(30.0)
    a = np.stack([40.0 * f, -40.0 * (f >= 15), np.full(f.size, 800.0)], axis=1)
    b = a + np.array([0.0, 55.0, 0.0])
    missing = {(0, k) for k in range(15, 18)}
    field, xyz, who = _cloud([a, b], seed=seed, noise_mm=0.5, missing=missing)
    ids = _identities(track_points(field, xyz, TrackingParams()), who)
    assert all(len(s) == 1 for s in ids)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_two_point_tracks_next_marker_leaves_both_its_points(seed):
    """Marker A (2.6 mm/field) is hidden for fields 5-11 and its track ends; its neighbour
    B, 23 mm away, is seen in fields 10-11 only; at field 12 B's two-point track takes A's
    point (22 mm from its prediction, in its gate). The cut test needs three samples
    before a cut, and the stray-end test split off B's first point only: the second goes
    too, and no piece holds both (OptiTrack at 160 Hz, sample_OptiTrack_walking)."""
    f = np.arange(40.0)[:, None]
    a = np.hstack([2.6 * f, 1.8 * f, 0.4 * f + 400.0])
    paths = [a, a + [13.6, 16.2, -8.0]]
    paths += [np.hstack([2.0 * f, 300.0 * k + 0 * f, 900 + 0 * f]) for k in range(1, 4)]
    missing = {(0, k) for k in range(5, 12)} | {(1, k) for k in range(40) if k not in (10, 11)}
    field, xyz, who = _cloud(paths, seed=seed, noise_mm=0.2, missing=missing)
    ids = _identities(track_points(field, xyz, TrackingParams()), who)
    assert all(len(s) == 1 for s in ids)
    assert {0} in ids and {1} in ids
