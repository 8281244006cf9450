"""A rigid cluster's markers predict each other (:meth:`kisscal.tracking.live.Live._carry`)."""

import numpy as np
import pytest

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
    each track to its own LED: no piece holds two LEDs. Without it (radius 0), some do."""
    field, xyz, who = _cloud(_shaken_hand(8, 150), seed=seed, noise_mm=0.5, missing=_HIDDEN)
    carried = _identities(track_points(field, xyz, TrackingParams()), who)
    assert all(len(s) == 1 for s in carried)
    own = _identities(track_points(field, xyz, TrackingParams(cluster_radius_mm=0.0)), who)
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
