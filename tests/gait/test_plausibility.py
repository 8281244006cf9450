"""A wrong ``rate_hz`` shows in cadence, walking speed or walk ratio outside human walking."""

from __future__ import annotations

import pytest

from kisscal.gait import GaitParams, gait_markers, spatiotemporal_parameters
from kisscal.gait.events import detect_events
from kisscal.gait.spatiotemporal import outside_walking
from kisscal.markersets import marker_set
from tests.gait import _real, _synth


@pytest.mark.parametrize(
    ("told_hz", "doubts"),
    [
        (100.0, ()),
        (60.0, ("walk ratio",)),  # issue 28's rate_hz = 30 for 50 Hz cameras
        (25.0, ("cadence", "walk ratio")),
        (400.0, ("cadence", "walking speed")),
    ],
)
def test_cadence_speed_and_walk_ratio_out_of_human_range_name_the_rate(told_hz, doubts) -> None:
    """A 1.1 m/s walker filmed at 100 Hz, processed as if at ``told_hz``: times scale by
    100 / told_hz, so at 25 Hz the cadence is a quarter (about 27 steps/min) and at
    400 Hz four times (about 430 steps/min, 4.4 m/s). At 60 Hz (issue 28: rate_hz = 30
    for 50 Hz cameras) cadence and speed are those of a slow walker, 61 steps/min and
    0.66 m/s, but the steps are still 0.65 m long: the walk ratio is 1.67x an adult's."""
    motion = _synth.walker(5, 100.0, heading_deg=30.0, height_m=1.75, speed_m_s=1.1)
    by_name = dict(zip(motion.names, motion.xyz_mm.transpose(1, 0, 2), strict=True))
    markers = gait_markers(by_name, told_hz, marker_set("kiss"))
    found = outside_walking(
        spatiotemporal_parameters(detect_events(markers), markers), GaitParams()
    )
    assert [f.split(" (")[0].rsplit(" ", 2)[0] for f in found] == list(doubts)
    if "cadence" in doubts:  # the cadence named is the walker's, scaled by the wrong rate
        truth = 120.0 / motion.truth.stride_time_s
        assert float(found[0].split()[1]) == pytest.approx(truth * told_hz / 100.0, rel=0.05)


def test_no_real_walk_is_doubted() -> None:
    """The bounds hold on the real trials of fixtures/real/gait (six systems, 60-250 Hz,
    walk ratios 0.0026-0.0074): a warning that cries wolf on real walks would be ignored."""
    for trial in _real.TRIALS:
        markers, _ = _real.load(trial)
        st = spatiotemporal_parameters(detect_events(markers), markers)
        assert outside_walking(st, GaitParams()) == [], trial.name
