"""Gait events on the real regression set (fixtures/real/gait/) against the marked events,
and the warnings a trial gets when it lacks events or full strides."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.gait import GaitParams, detect_events, gait_markers, spatiotemporal_parameters
from kisscal.markersets import marker_set
from kisscal.synth.motion import walking_trial
from tests.gait import _real
from tests.gait.real_events import Errors, score, table

#: Trials whose feet carry a heel marker (the others stand the ankle in for it).
HEEL = tuple(t.name for t in _real.TRIALS if not t.ankle)


@pytest.fixture(scope="module")
def marked():
    return table()


def test_the_set_is_real_and_varied() -> None:
    """At least ten trials with marked events, from more than one system and lab."""
    assert len(_real.TRIALS) >= 10
    counts = [sum(len(v) for v in _real.load(t)[1].values()) for t in _real.TRIALS]
    assert min(counts) >= 2 and sum(counts) >= 140
    systems = {t.system.split()[0] for t in _real.TRIALS}
    assert {"Vicon", "Motion", "Qualisys", "Codamotion", "BTS"} <= systems
    rates = {_real.load(t)[0].rate_hz for t in _real.TRIALS}
    assert {60.0, 100.0, 120.0, 250.0} <= rates


def test_foot_off_beats_zenis_rule_on_every_kind_of_file(marked) -> None:
    _, ours, zeni = marked
    assert len(ours.errors["foot_off"]) >= 65
    assert ours.mean_ms("foot_off") < 10.5 and ours.worst_ms("foot_off") < 40.0  # 8.1, 38
    assert ours.mean_ms("foot_off") < zeni.mean_ms("foot_off")
    assert sum(ours.missed.values()) <= 10


def test_the_later_foot_off_level_holds_on_the_half_it_was_not_chosen_on() -> None:
    """On filtered trajectories foot off is where the pitch rate has recovered a quarter
    of its fastest plantarflexion, not a fifth: chosen on the odd trials of the set
    (10.3 -> 9.5 ms mean, worst 34 ms both), it holds on the even ones (11.6 -> 9.5 ms,
    worst 24.5 ms both). Since 32 % (issue 26, chosen with biomechZoo's trials): 8.9 ms
    (worst 38) on the odd ones, 7.1 ms (worst 24.5) on the even ones."""
    fifth = GaitParams(off_recovery=(0.2, 0.2))
    ours, before = Errors(), Errors()
    for trial in _real.TRIALS[1::2]:
        gm, events = _real.load(trial)
        duration = gm.n_fields / gm.rate_hz
        ours.add(score(detect_events(gm), events, duration))
        before.add(score(detect_events(gm, fifth), events, duration))
    assert len(ours.errors["foot_off"]) >= 30
    assert ours.mean_ms("foot_off") < before.mean_ms("foot_off") - 1.0
    assert ours.worst_ms("foot_off") <= before.worst_ms("foot_off") + 1.0


def test_foot_off_is_not_early_on_filtered_nexus_trials() -> None:
    """biomechZoo's Nexus trials (six subjects, trajectories filtered before saving):
    there a corner of the pitch rate 13-15 ms before its first recovery level was taken
    for a sharp one and lay 15-35 ms before foot off. Against the marked events: bias
    -8.7 -> -3.8 ms, mean 13.8 -> 11.9 ms; against the plates' contacts: bias -6.8 ->
    +0.7 ms, mean 13.2 -> 9.2 ms. On their six held-out subjects (not kept here): bias
    -4.3 -> -0.6 ms, mean 10.1 -> 9.4 ms."""
    marked, plates = Errors(), Errors()
    for trial in _real.ZOO:
        for pooled, group in ((marked, "EVENT"), (plates, _real.PLATE_GROUP)):
            gm, events = _real.load(trial, group)
            pooled.add(score(detect_events(gm), events, gm.n_fields / gm.rate_hz))
    on_file, on_plates = (np.array(p.errors["foot_off"]) for p in (marked, plates))
    assert len(on_file) >= 30 and len(on_plates) >= 18
    assert abs(on_file.mean()) < 0.005 and marked.mean_ms("foot_off") < 12.5
    assert abs(on_plates.mean()) < 0.003 and plates.mean_ms("foot_off") < 10.5
    assert marked.worst_ms("foot_off") < 40.0


def test_foot_strike_where_the_heel_is_marked() -> None:
    """Treadmill (file events) and force-plate trials within the issue's bounds; the
    older overground files within 35 ms mean (their marked strikes away from the plates
    scatter about the heel's landing by about as much)."""
    pooled = Errors()
    for trial in _real.TRIALS:
        if trial.name not in HEEL:
            continue
        gm, events = _real.load(trial)
        err = score(detect_events(gm), events, gm.n_fields / gm.rate_hz)
        pooled.add(err)
        if trial.name in ("gaitalytics_treadmill", "opensim_walking5"):
            assert err.mean_ms("foot_strike") < 10.0, trial.name
            assert err.worst_ms("foot_strike") < 20.0, trial.name
            assert err.mean_ms("foot_off") < 10.0, trial.name
        assert not err.errors["foot_strike"] or err.mean_ms("foot_strike") < 35.0, trial.name
    assert pooled.mean_ms("foot_strike") < 10.6  # 10.0 ms (10.9 before the heel's rest)
    assert len(pooled.errors["foot_strike"]) >= 40


def test_foot_strike_where_the_ankle_stands_in_for_the_heel(marked) -> None:
    """Every trial, the four without a heel marker included (their heel a stand-in
    behind the ankle): 11.2 ms mean, 55 ms worst (12.2 and 57 ms before a heel at rest
    on landing that sank on under the load struck where it came to rest,
    vicon_ws44_plugingait's; 13.8 and 75 ms before a flat or forefoot landing struck
    where the foot's tip lands, vicon_2198928's; 14.2 before the heel had to swing
    furthest forward first; 19.2 and 83 ms with the ankle marker itself as the heel)."""
    _, ours, _ = marked
    assert len(ours.errors["foot_strike"]) >= 75
    assert ours.mean_ms("foot_strike") < 12.0
    assert ours.worst_ms("foot_strike") < 57.0


def test_the_heel_stand_in_holds_on_trials_it_was_not_chosen_on() -> None:
    """Its 40 mm were chosen on the ankle markers of four trials that also carry heel
    markers (their source files, not kept here); on the four trials without a heel
    marker its foot strikes are far closer to the marked ones than the ankle marker's
    own (15.4 against 46 ms mean; 23.6 before forefoot landings), and its foot offs no
    worse (same pitch line)."""
    stand_in, ankle = Errors(), Errors()
    for trial in (t for t in _real.TRIALS if t.ankle):
        for pooled, use in ((stand_in, True), (ankle, False)):
            gm, events = _real.load(trial, stand_in=use)
            pooled.add(score(detect_events(gm), events, gm.n_fields / gm.rate_hz))
            assert bool(gm.heel_from_ankle) == use
    assert len(stand_in.errors["foot_strike"]) >= 16
    assert stand_in.mean_ms("foot_strike") < 0.7 * ankle.mean_ms("foot_strike")
    assert stand_in.mean_ms("foot_strike") < 26.5
    assert stand_in.mean_ms("foot_off") <= ankle.mean_ms("foot_off") + 0.5


def test_held_out_gait_pig() -> None:
    """A C3D.org file kept out of the set and run blind first (its trimmed copy is
    committed since): gait-pig's marked events, 50 Hz, ankle stand-in. Its foot strikes
    came 45 ms early (54 worst) while the heel's rounded descent turned its corner before
    the heel had swung furthest forward: bounded by that, 24 ms (28 worst), Zeni's 26.
    The eight held-out files scored against their plates need ``$KISSCAL_C3D_CACHE``:
    ``python -m tests.gait.real_events held-out``."""
    pig = next(t for t in _real.HELD_OUT if t.name == "heldout_gait_pig")
    gm, events = _real.load(pig)
    ours = score(detect_events(gm), events, gm.n_fields / gm.rate_hz)
    assert len(ours.errors["foot_strike"]) >= 4
    assert ours.mean_ms("foot_strike") < 27.0 and ours.worst_ms("foot_strike") < 32.0
    assert ours.mean_ms("foot_off") < 12.0


def test_a_treadmill_walk_is_walking() -> None:
    """The pelvis hardly moves in the lab: every stride still gives its events."""
    trial = next(t for t in _real.TRIALS if t.name == "gaitalytics_treadmill")
    gm, _ = _real.load(trial)
    found = detect_events(gm)
    assert not found.warnings
    for side in ("left", "right"):
        assert len(found.times(side, "foot_strike")) >= 10
        assert len(found.times(side, "foot_off")) >= 10
    st = spatiotemporal_parameters(found, gm)
    assert 100.0 < st.mean("cadence", "left") < 112.0  # its 1.13 s strides
    # Lengths on the belt: the walking speed is the belt's, which carries a heel in
    # mid-stance back through the lab (measured here from the heel alone).
    heel = gm.heel["left"]
    strikes, offs = found.times("left", "foot_strike"), found.times("left", "foot_off")
    belt = []
    for t0 in strikes:
        t1 = offs[offs > t0][:1]
        if len(t1):
            i, j = round((t0 + 0.3 * (t1[0] - t0)) * 100), round((t0 + 0.7 * (t1[0] - t0)) * 100)
            belt.append(np.linalg.norm(heel[j, :2] - heel[i, :2]) / ((j - i) / 100.0) / 1000.0)
    for side in ("left", "right"):
        assert st.mean("walking_speed", side) == pytest.approx(np.median(belt), rel=0.05)
        assert 0.03 < st.mean("step_width", side) < 0.15


def _kiss(motion):
    kiss = marker_set("kiss")
    return gait_markers(
        dict(zip(motion.names, motion.xyz_mm.transpose(1, 0, 2), strict=True)), 100.0, kiss
    )


def test_a_4s_synthetic_kiss_walk_has_strikes_or_says_why() -> None:
    """The kinematic walker's heel never lands first: its strikes come from Zeni's
    crossing, with a warning, and its strides are whole."""
    gm = _kiss(walking_trial(0, 400, 100.0))
    found = detect_events(gm)
    for side in ("left", "right"):
        assert len(found.times(side, "foot_strike")) >= 2
    assert any("no heel-strike pattern" in w for w in found.warnings)
    st = spatiotemporal_parameters(found, gm)
    assert sum(len(st.values[("stride_time", s)]) for s in ("left", "right")) >= 2


def test_a_foot_without_a_heel_marker_gets_a_stand_in_behind_the_ankle() -> None:
    """The grounded walker without its heel markers: the set's ankle markers stand in,
    the log says so, and the events stay within a few ms of its true contacts."""
    m = walking_trial(1, 600, 100.0, path_mm=5000, model="grounded")
    kiss = marker_set("kiss")
    trial = dict(zip(m.names, m.xyz_mm.transpose(1, 0, 2), strict=True))
    gm = gait_markers({k: v for k, v in trial.items() if k != "LHEE"}, 100.0, kiss)
    assert gm.heel_from_ankle == ("left",) and gm.names["left_heel"] == "LANK"
    found = detect_events(gm)
    assert any(w.startswith("left: no heel marker") and "LANK" in w for w in found.warnings)
    for event, bound in (("foot_strike", 0.005), ("foot_off", 0.010)):
        true = m.truth.events.times("left", event)
        err = np.abs(found.times("left", event)[:, None] - true).min(axis=1)
        assert len(err) >= 4 and err.max() < bound, event
    empty = dict(trial, LHEE=np.full_like(trial["LHEE"], np.nan))  # a heel with no data
    assert gait_markers(empty, 100.0, kiss).heel_from_ankle == ("left",)
    with pytest.raises(KisscalError, match="no left heel marker"):
        gait_markers({k: v for k, v in trial.items() if k not in ("LHEE", "LANK")}, 100.0, kiss)


def test_warnings_name_the_reason() -> None:
    short = detect_events(_kiss(walking_trial(0, 100, 100.0, model="grounded")))
    assert any("too short" in w for w in short.warnings)
    m = walking_trial(1, 400, 100.0, model="grounded")
    gm = _kiss(m)
    holed = dict(gm.heel, left=np.where(np.arange(400)[:, None] < 300, np.nan, gm.heel["left"]))
    gaps = detect_events(_real.GaitMarkers(gm.pelvis, holed, gm.toe, 100.0, gm.names))
    left = [w for w in gaps.warnings if w.startswith("no full stride on the left")]
    assert left and "the left heel marker (LHEE) is missing in 75 %" in left[0]
    kiss = marker_set("kiss")
    still = np.broadcast_to(kiss.template_mm, (300, len(kiss), 3))
    noisy = still + np.random.default_rng(0).normal(0, 0.5, still.shape)
    stand = gait_markers(dict(zip(kiss.names, noisy.transpose(1, 0, 2), strict=True)), 100.0, kiss)
    assert [w for w in detect_events(stand).warnings if w.startswith("no walking")]
    assert detect_events(gm).warnings == ()
    # The same walk as a lab with y up would store it: the warning names the axis.
    y_up = _real.GaitMarkers(
        tuple(p[:, [0, 2, 1]] for p in gm.pelvis),
        {k: v[:, [0, 2, 1]] for k, v in gm.heel.items()},
        {k: v[:, [0, 2, 1]] for k, v in gm.toe.items()},
        100.0,
        gm.names,
    )
    assert any("along +y, not +z" in w for w in detect_events(y_up).warnings)
