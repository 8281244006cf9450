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


def test_kinematic_walker_defaults_are_unchanged() -> None:
    """Values of walking_trial(1, 50) before the grounded walker and its options existed."""
    m = walking_trial(1, 50)
    expected = {
        (0, 0): [747.0901179485347, 28.80726985404621, 1009.6583945848884],
        (17, 7): [31.939057817801984, 140.12838719217476, 92.03301786046597],
        (49, 14): [-1117.03581902923, -37.40273288224922, 189.08028282537623],
    }
    for (f, k), xyz in expected.items():
        np.testing.assert_allclose(m.xyz_mm[f, k], xyz, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        m.capsules_mm[33, 4],
        [[-215.73036071371428, -65.2660224660127, 903.6097923151298],
         [-303.9855281023536, -70.68112501953993, 482.7990247561971]],
        rtol=0, atol=1e-9,
    )  # fmt: skip
    assert m.truth is None


@pytest.mark.parametrize("model", ["kinematic", "grounded"])
def test_height_heading_and_start_options(model: str) -> None:
    base = walking_trial(2, 100, model=model, heading_deg=0.0, start_mm=(0.0, 0.0))
    tall = walking_trial(
        2, 100, model=model, height_m=1.9, heading_deg=135.0, start_mm=(500.0, -200.0)
    )
    np.testing.assert_allclose(
        tall.xyz_mm[0, 0, :2], base.xyz_mm[0, 0, :2] * 0 + [500, -200], atol=200
    )
    sacrum = tall.xyz_mm[:, tall.names.index("SACR"), :2]
    direction = sacrum[-1] - sacrum[0]
    assert np.degrees(np.arctan2(direction[1], direction[0])) == pytest.approx(135.0, abs=3.0)
    pairs = [p for p in base.segments if p[0][1:] in ("KNE", "ANK") and p[1][1:] in ("KNE", "ANK")]
    for a, b in pairs:  # segment lengths scale with stature
        d = [
            np.linalg.norm(m.xyz_mm[0, m.names.index(a)] - m.xyz_mm[0, m.names.index(b)])
            for m in (base, tall)
        ]
        assert d[1] / d[0] == pytest.approx(1900.0 / 1755.0, rel=1e-9)


def _contact_gaps(truth, side: str) -> np.ndarray:
    """Height above the floor of the lowest of the foot's heel, ball and toe-tip spheres."""
    keys = [f"{side}_{k}" for k in ("heel", "ball", "tip")]
    return np.min([truth.spheres_mm[k][:, 2] - truth.sphere_radius_mm[k] for k in keys], axis=0)


@pytest.mark.parametrize(("height_m", "speed", "heading"), [(1.5, 0.6, 20.0), (1.9, 1.25, 230.0)])
def test_grounded_walker_feet_touch_the_floor_without_sliding(height_m, speed, heading) -> None:
    rate = 1000.0
    m = walking_trial(
        3,
        3000,
        rate,
        path_mm=speed * 2999,
        model="grounded",
        height_m=height_m,
        heading_deg=heading,
    )
    tr, t = m.truth, np.arange(3000) / rate
    assert tr.nominal()["walking_speed"] == pytest.approx(speed)
    for side in ("left", "right"):
        gap = _contact_gaps(tr, side)
        strikes, offs = tr.events.times(side, "foot_strike"), tr.events.times(side, "foot_off")
        assert len(strikes) >= 2 and len(offs) >= 2
        assert gap.min() > -1e-9  # never below the floor
        for fs in strikes:  # the heel reaches the floor at foot strike, not before
            i = round(fs * rate)
            heel = tr.spheres_mm[f"{side}_heel"][:, 2] - tr.sphere_radius_mm[f"{side}_heel"]
            assert heel[i + 1] < 1e-9 < heel[i - 2] and np.all(np.diff(heel[i - 30 : i]) < 0)
            off = offs[offs > fs]
            if len(off):  # on the floor through stance, off it through swing
                stance = (t > fs + 0.002) & (t < off[0] - 0.002)
                assert np.abs(gap[stance]).max() < 1e-9
                nxt = strikes[strikes > off[0]]
                if len(nxt):
                    assert gap[(t > off[0] + 0.002) & (t < nxt[0] - 0.002)].min() > 0.0
        # no slip: in foot flat the heel and ball spheres stand still
        heel_c, ball_c = tr.spheres_mm[f"{side}_heel"], tr.spheres_mm[f"{side}_ball"]
        flat = (np.abs(heel_c[:, 2] - tr.sphere_radius_mm[f"{side}_heel"]) < 1e-9) & (
            np.abs(ball_c[:, 2] - tr.sphere_radius_mm[f"{side}_ball"]) < 1e-9
        )
        v = np.linalg.norm(np.gradient(heel_c, t, axis=0), axis=1)
        assert flat.sum() > 100 and np.median(v[flat]) < 1e-6
        # heel rocker: the heel sphere rolls (centre speed = radius x pitch rate)
        d = ball_c - heel_c
        pitch = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
        rocker = (np.abs(heel_c[:, 2] - tr.sphere_radius_mm[f"{side}_heel"]) < 1e-9) & (
            pitch > 0.01
        )
        rolling = tr.sphere_radius_mm[f"{side}_heel"] * np.abs(np.gradient(pitch, t))
        inner = rocker & np.roll(rocker, 2) & np.roll(rocker, -2)  # away from each run's ends
        assert inner.sum() > 20
        np.testing.assert_allclose(v[inner], rolling[inner], rtol=0.02, atol=1.0)


def test_grounded_walker_is_a_rigid_body_chain_outside_its_capsules() -> None:
    m = walking_trial(6, 200, 100.0, model="grounded", height_m=1.6, heading_deg=300.0)
    for a, b in m.segments:
        d = np.linalg.norm(m.xyz_mm[:, m.names.index(a)] - m.xyz_mm[:, m.names.index(b)], axis=1)
        assert np.ptp(d) < 1e-6, (a, b)
    xyz, caps = m.xyz_mm[:, :, None, :], m.capsules_mm[:, None]
    assert np.all(
        segment_distance(xyz, xyz, caps[..., 0, :], caps[..., 1, :]) > m.capsule_radius_mm
    )
