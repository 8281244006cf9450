"""Synthetic motion: the walker, the stick and the thrown marker keep their physics."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.synth.motion import (
    G_MM_S2,
    STICK_LENGTH_MM,
    gait_marker_names,
    stick_trial,
    throw_trial,
    walking_trial,
)
from kisscal.synth.scene import segment_distance


@pytest.mark.parametrize("n_markers", [13, 15])
def test_walker_segments_are_rigid(n_markers: int) -> None:
    m = walking_trial(seed=2, n_fields=150, n_markers=n_markers)
    assert m.names == gait_marker_names(n_markers)
    for a, b in m.segments:
        d = np.linalg.norm(m.xyz_mm[:, m.names.index(a)] - m.xyz_mm[:, m.names.index(b)], axis=1)
        assert np.ptp(d) < 1e-6, (a, b)


def test_walker_stays_on_the_floor_and_moves_forward() -> None:
    m = walking_trial(seed=1, n_fields=250)
    z = m.xyz_mm[..., 2]
    assert z.min() > 10.0  # marker centres above the floor
    feet = [m.names.index(n) for n in ("RHEE", "RTOE", "LHEE", "LTOE")]
    assert z[:, feet].min() < 60.0  # feet reach the floor
    sacrum_x = m.xyz_mm[:, m.names.index("SACR"), 0]
    assert abs(sacrum_x[-1] - sacrum_x[0]) > 2400.0  # crosses the whole volume


def test_markers_lie_outside_their_body_capsules() -> None:
    m = walking_trial(seed=3, n_fields=100)
    xyz = m.xyz_mm[:, :, None, :]
    caps = m.capsules_mm[:, None]
    d = segment_distance(xyz, xyz, caps[..., 0, :], caps[..., 1, :])
    assert np.all(d > m.capsule_radius_mm)


def test_stick_has_the_seed_length() -> None:
    s = stick_trial(seed=1)
    d = np.linalg.norm(s.xyz_mm[:, 0] - s.xyz_mm[:, 1], axis=1)
    assert np.allclose(d, STICK_LENGTH_MM)
    assert s.n_fields == 200  # 4 s at 50 Hz


def test_thrown_marker_is_ballistic() -> None:
    m = throw_trial(seed=1)
    t = np.arange(m.n_fields) / m.rate_hz
    z = m.xyz_mm[:, 0, 2]
    assert np.polyfit(t, z, 2)[0] * 2 == pytest.approx(-G_MM_S2, rel=1e-9)
