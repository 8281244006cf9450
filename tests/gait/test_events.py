"""Gait events against the grounded walker's true foot contacts, and walking5's force plates."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.gait import GaitParams, detect_events, gait_markers, progression
from kisscal.markersets import marker_set
from tests.gait import _synth, _walking5


def _pooled(rate_hz: float, n: int, seed: int):
    errors = {"foot_strike": [], "foot_off": []}
    missed = extra = 0
    for k, (heading, height, speed) in enumerate(_synth.grid(n, seed)):
        tr = _synth.trial(100 * seed + k, rate_hz, heading, height, speed)
        sc = _synth.score(tr.events, tr.truth, (tr.motion.n_fields - 1) / rate_hz)
        for e in errors:
            errors[e] += sc.errors_s[e]
        missed += sum(sc.missed.values())
        extra += sum(sc.extra.values())
    return {e: np.abs(v) for e, v in errors.items()}, missed, extra


@pytest.mark.parametrize(("rate_hz", "mae_ms", "max_ms"), [(100.0, 5.0, 25.0), (50.0, 7.0, 40.0)])
def test_events_match_true_contacts_any_heading_and_height(
    rate_hz: float, mae_ms: float, max_ms: float
) -> None:
    """Headings over 360 degrees, statures 1.5-1.9 m, 0.7-1.4 m/s, 0.5 mm noise (the bar
    is 10 ms mean absolute error; at 50 Hz a field is 20 ms, so single events may miss
    by up to two fields)."""
    errors, missed, extra = _pooled(rate_hz, 8, seed=1)
    assert missed == 0 and extra == 0
    for event, err in errors.items():
        assert len(err) >= 40, event
        assert err.mean() * 1000 < mae_ms, (event, err.mean())
        assert err.max() * 1000 < max_ms, (event, err.max())


def test_a_turning_walk_keeps_its_events() -> None:
    tr = _synth.trial(5, 100.0, 30.0, 1.7, 1.0, duration_s=6.0, turn_deg=120.0)
    sc = _synth.score(tr.events, tr.truth, (tr.motion.n_fields - 1) / 100.0)
    assert sum(sc.missed.values()) == 0 and sum(sc.extra.values()) == 0
    for event, err in sc.errors_s.items():
        assert np.abs(err).mean() < 0.006, event
    direction, _ = progression(tr.markers)
    heading = np.degrees(np.arctan2(direction[:, 1], direction[:, 0]))
    turned = (heading[-60] - heading[60] + 180.0) % 360.0 - 180.0
    assert turned == pytest.approx(120.0 * (len(heading) - 121) / len(heading), abs=8.0)


def test_partial_strides_at_the_ends_give_no_invented_events() -> None:
    """Cut a trial anywhere: every event found is a true one, none near the cuts is made up."""
    tr = _synth.trial(7, 100.0, 250.0, 1.6, 1.2, duration_s=5.0)
    names = tr.motion.names
    kiss = marker_set("kiss")
    for start, stop in ((13, 377), (41, 290), (77, 431)):
        xyz = tr.motion.xyz_mm[start:stop] + np.random.default_rng(start).normal(0, 0.5, (1,))
        gm = gait_markers(dict(zip(names, xyz.transpose(1, 0, 2), strict=True)), 100.0, kiss)
        found = detect_events(gm)
        true_times = {
            key: tr.truth.events.times(*key) - start / 100.0
            for key in {(s, e) for s, e in zip(found.side, found.event, strict=True)}
        }
        for side, event, t in zip(found.side, found.event, found.time_s, strict=True):
            assert np.abs(true_times[(side, event)] - t).min() < 0.02
        assert len(found) >= 4


def test_a_gap_in_the_heel_loses_only_the_events_it_covers() -> None:
    tr = _synth.trial(9, 100.0, 80.0, 1.8, 1.0)
    heel = tr.markers.heel["left"].copy()
    fs = tr.truth.events.times("left", "foot_strike")
    hole = slice(int(fs[1] * 100) - 10, int(fs[1] * 100) + 10)
    heel[hole] = np.nan
    markers = _synth.GaitMarkers(
        tr.markers.pelvis, {**tr.markers.heel, "left": heel}, tr.markers.toe, 100.0, {}
    )
    found = detect_events(markers)
    sc = _synth.score(found, tr.truth, (tr.motion.n_fields - 1) / 100.0)
    assert sum(sc.extra.values()) == 0
    assert sc.missed == {"foot_strike": 1, "foot_off": 0}
    assert np.abs(found.times("left", "foot_strike") - fs[1]).min() > 0.3


def test_a_heel_lost_just_after_its_strike_keeps_the_strike() -> None:
    """A heel marker lost in early stance (as in c3d.org's PlugInC3D and Vicon_analysis,
    the heel gone 60-200 ms after a marked strike): the landing is in view, so the strike
    is found, at the truth; the gap hides nothing else."""
    tr = _synth.trial(9, 100.0, 80.0, 1.8, 1.0)
    fs = tr.truth.events.times("left", "foot_strike")
    for after_s in (0.06, 0.1):
        heel = tr.markers.heel["left"].copy()
        start = int(np.ceil((fs[1] + after_s) * 100))
        heel[start : start + 40] = np.nan
        markers = _synth.GaitMarkers(
            tr.markers.pelvis, {**tr.markers.heel, "left": heel}, tr.markers.toe, 100.0, {}
        )
        found = detect_events(markers)
        sc = _synth.score(found, tr.truth, (tr.motion.n_fields - 1) / 100.0)
        assert sum(sc.extra.values()) == 0 and sum(sc.missed.values()) == 0, after_s
        assert np.abs(found.times("left", "foot_strike") - fs[1]).min() < 0.010, after_s


def test_a_pelvis_seen_after_the_feet_keeps_the_strike_between() -> None:
    """The pelvis markers found 80 ms after a foot strike, the feet seen before it (as in
    c3d.org's Vicon_analysis): the pelvis keeps its first velocity back to the strike
    (walking speed changes little within ``direction_s``), so the strike is found."""
    tr = _synth.trial(9, 100.0, 80.0, 1.8, 1.0)
    fs = tr.truth.events.times("left", "foot_strike")
    pelvis = [p.copy() for p in tr.markers.pelvis]
    for p in pelvis:
        p[: int((fs[1] + 0.08) * 100)] = np.nan
    markers = _synth.GaitMarkers(tuple(pelvis), tr.markers.heel, tr.markers.toe, 100.0, {})
    found = detect_events(markers)
    assert np.abs(found.times("left", "foot_strike") - fs[1]).min() < 0.010
    sc = _synth.score(found, tr.truth, (tr.motion.n_fields - 1) / 100.0)
    assert sum(sc.extra.values()) == 0


def test_standing_still_has_no_events() -> None:
    kiss = marker_set("kiss")
    still = np.broadcast_to(kiss.template_mm, (300, len(kiss), 3))
    noisy = still + np.random.default_rng(0).normal(0, 0.5, still.shape)
    gm = gait_markers(dict(zip(kiss.names, noisy.transpose(1, 0, 2), strict=True)), 100.0, kiss)
    assert len(detect_events(gm)) == 0


def test_walking5_events_agree_with_its_force_plates() -> None:
    gm, _ = _walking5.load()
    found = detect_events(gm)
    assert found.rate_hz == 250.0
    for side in ("left", "right"):  # two full strides per side in view
        assert len(found.times(side, "foot_strike")) >= 2
        assert len(found.times(side, "foot_off")) >= 2
    plates = _walking5.plate_events()
    assert len(plates) == 3  # right strike on plate 2; left and right offs
    for p in plates:
        error = np.abs(found.times(p.side, p.event) - p.time_s).min()
        assert error < 0.010, (p, error)


def test_missing_markers_are_one_line_errors() -> None:
    kiss = marker_set("kiss")
    with pytest.raises(KisscalError, match="no left heel marker"):
        gait_markers({"SACR": np.zeros((5, 3))}, 100.0, kiss)
    with pytest.raises(KisscalError, match="no pelvis marker"):
        gait_markers({"LHEE": np.zeros((5, 3))}, 100.0, kiss)
    with pytest.raises(KisscalError, match=r"\[gait\] strike_window"):
        GaitParams(strike_window=(0.1, -0.1))


def test_foot_strike_is_where_the_heel_lands_not_where_it_sinks_lowest() -> None:
    """A heel marker that lands at 1.0 s and then sinks 0.8 mm more over 150 ms (the
    foot rolling down to foot flat, a soft heel pad, an ankle standing in for the heel)
    has its lowest sample 150 ms late: the strike is still its landing."""
    from kisscal.gait.landing import foot_strikes

    rate, t0, sink_s = 100.0, 1.0, 0.15
    t = np.arange(200) / rate
    tau = t - t0
    z = np.where(
        tau < 0,
        0.8 - 200.0 * tau + 2000.0 * tau**2,  # terminal swing, down at 0.2 m/s on landing
        np.where(tau < sink_s, 0.8 * (1 - tau / sink_s), 500.0 * (tau - sink_s) ** 2),
    )
    z = z + np.random.default_rng(0).normal(0.0, 0.1, len(t))
    heel = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
    assert abs(t[np.argmin(z)] - t0) > 0.1  # the lowest sample is far from the landing
    coarse = np.array([t0 - 0.02])  # Zeni's crossing comes a little early
    (found,), zeni_only = foot_strikes(t, heel, coarse, 1.1, GaitParams())
    assert zeni_only == 0
    assert abs(found - t0) < 0.005
    # Looked for around the lowest sample instead (no floor margin), it is missed.
    (late,), _ = foot_strikes(t, heel, coarse, 1.1, GaitParams(strike_floor_mm=1e-9))
    assert abs(late - t0) > 0.05


def test_a_heel_sinking_on_through_stance_still_lands_where_it_lands() -> None:
    """A heel marker that lands at 1.0 s and then sinks 2 mm more over 0.35 s (skin and
    a soft heel pad under it) is still falling at the end of the strike window: its
    landing is found all the same, not taken from Zeni's crossing."""
    from kisscal.gait.landing import foot_strikes

    rate, t0 = 200.0, 1.0
    t = np.arange(400) / rate
    tau = t - t0
    z = np.where(
        tau < 0,
        -300.0 * tau + 2000.0 * tau**2,  # terminal swing, down at 0.3 m/s on landing
        np.where(tau < 0.35, -2.0 * tau / 0.35, -2.0 + 800.0 * (tau - 0.35) ** 2),
    )
    heel = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=1)
    coarse = np.array([t0 - 0.02])
    (found,), zeni_only = foot_strikes(t, heel, coarse, 1.1, GaitParams())
    assert zeni_only == 0
    assert abs(found - t0) < 0.006
    # Without looking on past the window it is taken from Zeni's crossing alone.
    (zeni,), fallback = foot_strikes(t, heel, coarse, 1.1, GaitParams(strike_sink=0.2))
    assert fallback == 1 and zeni == coarse[0]


def _landing(rate: float, t0: float, noise_mm: float, on_tip: bool) -> tuple:
    """A foot landing at ``t0``, falling at 0.3 m/s, on its tip (the heel 0.12 rad up)
    or on its heel (the toes 0.3 rad up), then rolling down about that point to foot
    flat in 80 ms; heel off 0.38 s after the landing. Time, heel and toe markers (150 mm
    apart, the tip 40 mm ahead of the toe marker, both 40 mm up at foot flat)."""
    t = np.arange(round(2 * t0 * rate)) / rate
    tau = t - t0
    drop = np.where(tau < 0, -300.0 * tau, 0.0)  # the landing point's height
    start = 0.12 if on_tip else -0.3  # the heel's pitch up (the toes down)
    pitch = np.where(tau < 0, start, start * np.clip(1 - tau / 0.08, 0, 1) ** 2)
    pitch = pitch + np.where(tau > 0.38, 2.0 * (tau - 0.38) ** 2, 0.0)  # heel off
    forward = np.stack([np.cos(pitch), np.zeros_like(t), -np.sin(pitch)], axis=1)
    pivot = np.stack([np.zeros_like(t), np.zeros_like(t), 40.0 + drop], axis=1)
    heel = pivot - 190.0 * forward if on_tip else pivot
    noise = np.random.default_rng(1).normal(0.0, noise_mm, (2, len(t), 3))
    return t, heel + noise[0], heel + 150.0 * forward + noise[1]


def test_a_forefoot_landing_strikes_when_the_tip_lands_not_the_heel() -> None:
    """A flat or forefoot landing (Perry 1992): the foot's tip lands at 1.0 s while the
    heel marker is still 20 mm up and falling; it comes down 80 ms later. Foot strike is
    the tip's landing (within a field: the tip is 1 mm up 3 ms before), not the heel's;
    a heel-first landing keeps the heel's (its tip lands 80 ms later)."""
    from kisscal.gait.landing import foot_strikes

    coarse = np.array([0.98])
    for rate in (60.0, 100.0, 250.0):
        for on_tip in (True, False):
            t, heel, toe = _landing(rate, 1.0, 0.3, on_tip)
            (heel_only,), _ = foot_strikes(t, heel, coarse, 1.1, GaitParams())
            (found,), _ = foot_strikes(t, heel, coarse, 1.1, GaitParams(), toe)
            assert abs(found - 1.0) < 1.0 / rate, (rate, on_tip)
            if on_tip:
                assert heel_only - 1.0 > 0.05, rate  # the heel lands late
            else:
                assert abs(found - heel_only) < 0.002, rate  # the heel's landing


def test_a_heel_at_rest_on_landing_then_sinking_under_load_lands_on_landing() -> None:
    """A heel-first landing at 1.0 s whose heel marker rests there, then sinks 4 mm
    between 40 and 70 ms (loading response: soft tissue, a shoe's heel) and stays low:
    its lowest comes 70 ms late, but foot strike is where it came to rest. Without the
    toe marker (no pitch to tell a hover in terminal swing from a rest) it is late."""
    from kisscal.gait.landing import foot_strikes

    coarse = np.array([0.98])
    for rate in (60.0, 100.0, 250.0):
        t, heel, toe = _landing(rate, 1.0, 0.1, on_tip=False)
        heel[:, 2] -= 4.0 * np.clip((t - 1.04) / 0.03, 0, 1)
        (late,), _ = foot_strikes(t, heel, coarse, 1.1, GaitParams())
        (found,), _ = foot_strikes(t, heel, coarse, 1.1, GaitParams(), toe)
        assert late - 1.0 > 0.04, rate
        assert abs(found - 1.0) < 1.0 / rate, rate


def test_marker_noise_tells_raw_trajectories_from_filtered_ones() -> None:
    """The walker's 0.5 mm of noise per coordinate is measured as such; the same trial
    low-pass filtered as labs save it (Butterworth, 6 Hz, zero lag) falls far below
    ``filtered_mm`` (its foot offs then need a smaller sharp-corner margin)."""
    from scipy.signal import butter, filtfilt

    from kisscal.gait.events import noise_mm

    tr = _synth.trial(7, 100.0, 30.0, 1.7, 1.1)
    assert noise_mm(tr.markers.pelvis) == pytest.approx(_synth.NOISE_MM, rel=0.15)
    b, a = butter(2, 6.0 / 50.0)
    smooth = tuple(filtfilt(b, a, p, axis=0) for p in tr.markers.pelvis)
    assert noise_mm(smooth) < 0.2 * GaitParams().filtered_mm
