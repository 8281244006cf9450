"""A rigid cluster's markers predict each other (:meth:`kisscal.tracking.live.Live._carry`)."""

import numpy as np
import pytest

import kisscal.tracking.cluster as cluster
from kisscal.tracking import TrackingParams, track_points
from tests.tracking.test_tracker import _cloud, _identities

# Four LEDs of a hand, 40-60 mm apart (PhaseSpace's hand: 30-70 mm).
_HAND = np.array([[0.0, 0, 0], [45.0, 0, 0], [0, 40.0, 0], [20, 20, 35.0]])


def _shaken_hand(period_fields: float, amplitude_mm: float, n_fields: int = 90) -> list:
    """Paths of the hand's LEDs, shaken along x (and a third as much along y) with the
    given period and amplitude while turning 0.05 rad a field about the vertical."""
    f = np.arange(float(n_fields))
    phase = 2 * np.pi * f / period_fields
    centre = np.stack(
        [amplitude_mm * np.sin(phase), 0.3 * amplitude_mm * np.cos(phase), 1000.0 + 0 * f], axis=1
    )
    c, s = np.cos(0.05 * f), np.sin(0.05 * f)
    turn = np.zeros((n_fields, 3, 3))
    turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1], turn[:, 2, 2] = c, -s, s, c, 1
    return [centre + turn @ led for led in _HAND]


# Two LEDs hidden for a few fields: their tracks reappear as one-point tracks among the
# moving cluster.
_HIDDEN = {(1, k) for k in range(20, 23)} | {(2, k) for k in range(47, 49)}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_fast_hands_leds_are_predicted_by_their_cluster(seed):
    """A hand shaken at 30 Hz with a period of 8 fields: steps up to 118 mm and
    accelerations of 92 mm per field squared, so a track's own constant-velocity or
    quadratic prediction misses its LED by more than the LEDs are apart (and a reappearing
    LED's one-point track predicts no move at all). The cluster's common move carries
    each track to its own LED: no piece holds two LEDs. Without it (radius 0), and without
    the split of guessed first steps (``first_step_ratio`` 0: with it alone, seed 0 holds
    none either), some do."""
    field, xyz, who = _cloud(_shaken_hand(8, 150), seed=seed, noise_mm=0.5, missing=_HIDDEN)
    carried = _identities(track_points(field, xyz, TrackingParams()), who)
    assert all(len(s) == 1 for s in carried)
    alone = TrackingParams(cluster_radius_mm=0.0, first_step_ratio=0.0)
    own = _identities(track_points(field, xyz, alone), who)
    assert any(len(s) > 1 for s in own)


def test_a_slow_cluster_is_left_alone():
    """Slow enough that every track finds its LED where it predicted it, the cluster
    carries nothing: the tracks are those of the tracker without it."""
    field, xyz, _ = _cloud(_shaken_hand(60, 150), seed=0, noise_mm=0.5, missing=_HIDDEN)
    with_cluster = track_points(field, xyz, TrackingParams())
    without = track_points(field, xyz, TrackingParams(cluster_radius_mm=0.0))
    assert np.array_equal(with_cluster.track, without.track)
    assert np.allclose(with_cluster.xyz_mm, without.xyz_mm)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_neighbour_that_does_not_move_together_carries_nothing(seed):
    """Two markers 50 mm apart glide at 60 mm a field beside a third that swings up and
    down by 120 mm with a period of 6 fields (another limb, 50 mm away). The swinging one's
    track misses its own prediction, but its distance to the others changes: it is no
    cluster of theirs, nor they of its, and no piece mixes them (as without the cluster);
    the first field, where every track has just appeared, carries nothing either."""
    f = np.arange(90.0)
    glide = np.stack([60.0 * f, 0 * f, 1000 + 0 * f], axis=1)
    swing = glide + np.stack([0 * f, 50 + 0 * f, 120 * np.sin(2 * np.pi * f / 6)], axis=1)
    paths = [glide, swing, glide - np.array([0.0, 50.0, 0.0])]
    missing = {(0, 30), (0, 31), (1, 50)}
    field, xyz, who = _cloud(paths, seed=seed, noise_mm=0.5, missing=missing)
    assert all(len(s) == 1 for s in _identities(track_points(field, xyz, TrackingParams()), who))


def _hidden_runs(n_paths: int, n_fields: int, seed: int) -> set:
    """(path, field) pairs hidden: runs of 1-4 fields starting at 3 % of the fields."""
    rng = np.random.default_rng(seed)
    out = set()
    for k in range(n_paths):
        for start in np.flatnonzero(rng.random(n_fields) < 0.03):
            out |= {(k, f) for f in range(start, start + rng.integers(1, 5))}
    return out


def _holding_two(tracks, who) -> int:
    """Changes of true marker inside the pieces ``tracks`` (a piece of k LEDs counts k-1)."""
    return sum(len(s) - 1 for s in _identities(tracks, who))


def _pieces_holding_two(field, xyz, who) -> int:
    """:func:`_holding_two` of the tracker's pieces with the default parameters."""
    return _holding_two(track_points(field, xyz, TrackingParams()), who)


def test_a_track_that_breaks_its_cluster_is_cut(monkeypatch):
    """Two hands 100 mm apart shaken at 30 Hz with periods of 6 and 8 fields, their LEDs
    hidden for 1-4 fields at random: a track whose LED is hidden takes a neighbour's, and
    its distances to the LEDs it moved with jump. The tracker cuts it there
    (:func:`kisscal.tracking.cluster.broken`): in no trial do more pieces hold two LEDs
    than without the cut, and over the five trials fewer do (measured 0 against 4; 9
    against 21 when only a piece's first step was judged a guess)."""
    with_cut, without = [], []
    for seed in range(5):
        paths = _shaken_hand(6, 150) + [p + [60.0, 80, 0] for p in _shaken_hand(8, 150)]
        cloud = _cloud(paths, seed=seed, noise_mm=0.5, missing=_hidden_runs(8, 90, seed))
        with_cut.append(_pieces_holding_two(*cloud))
        with monkeypatch.context() as m:
            m.setattr(cluster, "broken", lambda *a: np.empty(0, dtype=np.int64))
            without.append(_pieces_holding_two(*cloud))
    assert all(a <= b for a, b in zip(with_cut, without, strict=True))
    assert sum(with_cut) < sum(without)


def test_broken_names_the_track_that_took_a_neighbours_point():
    """Four LEDs moved rigidly over five fields; in the sixth, track 0's LED is hidden and
    it takes track 1's point while track 1 coasts: its distance to track 2 jumps (40 ->
    60 mm), and both ends of it are named (which took the wrong point, three LEDs do not
    say); track 3, whose distances hold, is not; nobody when each takes its own point."""
    step = np.array([30.0, 10, 0])
    history = np.stack([_HAND + k * step for k in range(5)], axis=1)  # (4, 5, 3)
    n, fresh = np.full(4, 5), np.ones(4, dtype=bool)
    points = _HAND + 5 * step
    right = cluster.broken(history, n, fresh, points, np.arange(4), np.arange(4), 100.0, 10.0)
    assert right.size == 0
    rows, cols = np.array([0, 2, 3]), np.array([1, 2, 3])
    assert cluster.broken(history, n, fresh, points, rows, cols, 100.0, 10.0).tolist() == [0, 2]


def _no_joint_carry(pred, history, n, live, *args):
    """:func:`kisscal.tracking.cluster._joint_carry` carrying nobody."""
    return np.zeros(live.size, dtype=bool)


def _toe_off(leap: list, seed: int, n_fields: int = 60) -> tuple:
    """Two LEDs of a toe 30 mm apart, still for 30 fields, then stepping ``leap`` (mm a
    field) along the line from the trailing to the leading one, then still."""
    steps = np.zeros(n_fields)
    steps[30 : 30 + len(leap)] = leap
    lead = np.stack([np.cumsum(steps), np.zeros(n_fields), np.zeros(n_fields)], axis=1)
    return _cloud([lead, lead - [30.0, 0, 0]], seed=seed, noise_mm=0.5)


@pytest.mark.parametrize("seed", range(4))
def test_a_toe_off_is_followed_by_the_clusters_joint_move(seed, monkeypatch):
    """A toe-off at 30 Hz (PhaseSpace's toe LEDs: still, then 9, 43, 59 mm a field): at the
    43 mm leap the leading LED's track finds the trailing LED's point where it predicted
    itself (13 mm on from its last position) and the trailing LED's track finds nothing; the
    mean move of the points so assigned carries nobody. The move that carries both last
    positions onto the field's points (:func:`kisscal.tracking.cluster.joint_moves`) finds
    each its own: no piece holds both LEDs. Without it, one or two do in every trial."""
    field, xyz, who = _toe_off([9, 43, 59, 32, 8], seed)
    assert _holding_two(track_points(field, xyz, TrackingParams()), who) == 0
    monkeypatch.setattr(cluster, "_joint_carry", _no_joint_carry)
    assert _holding_two(track_points(field, xyz, TrackingParams()), who) > 0


def test_a_move_a_shifted_one_explains_as_well_is_nobodys():
    """Three markers 51 mm apart on a line (walking5's condyles and knee centre) all jump
    31 mm across it: the middle one's cluster holds all three, and only the true move
    explains them all; an end one's holds two, which a move one marker along the line
    explains as well as the true one: no move for it (before this rule it was carried
    one marker along, a switch)."""
    last = np.array([[0.0, 0, 0], [0, 51, 0], [0, 102, 0]])
    points = last + [-31.0, 0, 0]
    member = np.array([[1, 1, 0], [1, 1, 1], [0, 1, 1]], dtype=bool)
    found = np.full(3, -1)
    move, count, *_ = cluster.joint_moves(
        last, member, last + [5.0, 0, 0], points, found, np.full(3, 10.0)
    )
    assert count.tolist() == [0, 3, 0]
    assert np.allclose(move[1], [-31.0, 0, 0])


def test_a_one_point_tracks_first_step_to_a_neighbour_is_split_off():
    """The two hands of :func:`test_a_track_that_breaks_its_cluster_is_cut`, six trials:
    an LED found again starts a one-point track, which has no velocity, and its LED moves
    about as far in a field as its neighbours are apart, so the nearest point of the next
    field is often a neighbour's. A first step is split off as a guess while another point
    lies within ``first_step_ratio`` (2) times its length, not ``rival_ratio`` (1.35, a
    track with a velocity's miss): in no trial do more pieces hold two LEDs, and over the
    six fewer do (measured 0 against 3; 5 against 9 when a piece's first step alone was
    judged, not the steps after a guessed one too)."""
    guessed, rival = [], []
    for seed in range(6):
        paths = _shaken_hand(6, 150) + [p + [60.0, 80, 0] for p in _shaken_hand(8, 150)]
        field, xyz, who = _cloud(paths, seed=seed, noise_mm=0.5, missing=_hidden_runs(8, 90, seed))
        guessed.append(_holding_two(track_points(field, xyz, TrackingParams()), who))
        params = TrackingParams(first_step_ratio=TrackingParams().rival_ratio)
        rival.append(_holding_two(track_points(field, xyz, params), who))
    assert all(a <= b for a, b in zip(guessed, rival, strict=True))
    assert sum(guessed) < sum(rival)
