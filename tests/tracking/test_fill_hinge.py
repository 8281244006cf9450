"""Gap fill about the axis of a segment's two measured markers (kisscal.tracking.fill_hinge)
against truth."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from kisscal.tracking import TrackingParams
from kisscal.tracking.bodyfill import axis_fill
from kisscal.tracking.fill_hinge import hinge_fill
from kisscal.tracking.stretches import expected_errors
from tests.tracking.test_bodyfill import pelvis

N = 300


def rolling_foot(roll_deg: float = 40.0, noise_mm: float = 0.0, seed: int = 0) -> np.ndarray:
    """Ankle, toe and heel of a foot walking at 100 Hz that rolls by up to ``roll_deg``
    about its ankle-toe axis (pitching a little), as a foot does from heel strike to
    toe-off, plus a shank marker across the joint: (4, N, 3)."""
    t = np.arange(N) / 100.0
    roll = np.radians(roll_deg) * np.sin(2.0 * t)
    pitch = np.radians(10.0) * np.sin(3.0 * t)
    rot = Rotation.from_euler("xy", np.stack([roll, pitch], 1))
    shape = np.array([[0.0, 0, 0], [150, 0, -40], [-60, 40, -50]])
    move = np.stack([1000 * t, 30 * np.sin(t), 100 + 40 * np.sin(6 * t)], 1)
    foot = [rot.apply(p) + move for p in shape]
    shank = move + np.stack([0 * t, 0 * t, 350 + 0 * t], 1)
    rng = np.random.default_rng(seed)
    xyz = np.stack([*foot, shank])
    return xyz + rng.normal(0, noise_mm, xyz.shape)


def test_hinge_fill_follows_a_foot_rolling_about_its_axis():
    """The heel hidden for 0.3 s while the foot rolls: its circle about the ankle-toe
    axis holds, and the spline of its angle follows the roll the lab-held frame of the
    two-marker fill misses."""
    xyz = rolling_foot(noise_mm=0.3)
    truth = rolling_foot()
    cut = xyz.copy()
    cut[2, 120:150] = np.nan
    params = TrackingParams()
    got = hinge_fill(cut[2], cut, 2, 120, 150, params)
    assert got is not None
    assert sorted(got[1]) == [0, 1]
    err = np.sqrt(np.mean(np.sum((got[0] - truth[2, 120:150]) ** 2, axis=1)))
    assert err < 1.5
    # the frame held against the lab does not hold the heel still beside the gap
    assert axis_fill(cut[2], cut, 2, 120, 150, params) is None
    # its expected error, measured beside the gap, tells its true error within 2 mm
    expected = expected_errors(hinge_fill, cut[2], cut, 2, 120, 150, params)[0]
    assert abs(expected - err) < 2.0


def test_hinge_fill_tells_a_roll_too_fast_for_its_spline():
    """A foot turning back and forth within the gap: the spline of its angle misses it,
    and its expected error says so (above the 3 mm a fill is held to)."""
    xyz = rolling_foot()
    t = np.arange(N) / 100.0
    axis = xyz[1] - xyz[0]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    wobble = Rotation.from_rotvec(np.radians(30.0) * np.sin(25.0 * t)[:, None] * axis)
    xyz[2] = wobble.apply(xyz[2] - xyz[0]) + xyz[0]
    cut = xyz.copy()
    cut[2, 120:160] = np.nan
    params = TrackingParams()
    got = hinge_fill(cut[2], cut, 2, 120, 160, params)
    assert got is not None
    err = np.sqrt(np.mean(np.sum((got[0] - xyz[2, 120:160]) ** 2, axis=1)))
    assert err > 5.0
    assert expected_errors(hinge_fill, cut[2], cut, 2, 120, 160, params)[0] > 3.0


def test_hinge_fill_needs_two_markers_of_the_segment():
    """The shank marker across the joint is not rigid with the heel: with the toe hidden
    too, no pair carries it."""
    xyz = rolling_foot()
    t = np.arange(N) / 100.0
    xyz[3] += np.stack([60 * np.sin(4 * t), 0 * t, 0 * t], 1)
    cut = xyz.copy()
    cut[2, 120:150] = np.nan
    cut[1, 110:160] = np.nan
    assert hinge_fill(cut[2], cut, 2, 120, 150, TrackingParams()) is None


def test_hinge_fill_equals_the_truth_on_a_rigid_pelvis():
    """A rigid segment tilting about the two markers' axis: filled within 1 mm RMS (the
    spline of the tilt's angle is what errs)."""
    xyz = pelvis(tilt_deg=8.0)
    cut = xyz.copy()
    cut[2, 100:130] = np.nan
    got = hinge_fill(cut[2], cut, 2, 100, 130, TrackingParams())
    assert got is not None
    assert np.sqrt(np.mean(np.sum((got[0] - xyz[2, 100:130]) ** 2, axis=1))) < 1.0
