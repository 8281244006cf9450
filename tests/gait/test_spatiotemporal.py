"""Spatiotemporal parameters against the grounded walker's truth, and their table formats."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.gait import UNITS, GaitEvents, spatiotemporal_parameters
from tests.gait import _synth

RELATIVE = ("cadence", "walking_speed", "stride_time", "stride_length", "step_length")


@pytest.fixture(scope="module")
def trials():
    return [
        _synth.trial(200 + k, 100.0, heading, height, speed)
        for k, (heading, height, speed) in enumerate(_synth.grid(6, seed=3))
    ]


def test_parameters_are_within_one_percent_of_truth(trials) -> None:
    """Truth: the same definitions on the noise-free heel markers at the true contacts.
    Lengths and times within 1 %; step width (about 90 mm) within 2 %, i.e. 2 mm; stance,
    swing and double support (already % of the cycle) within 1 percentage point."""
    for tr in trials:
        true, found = _synth.true_spatiotemporal(tr), _synth.measured_spatiotemporal(tr)
        for side in ("left", "right"):
            for p in RELATIVE:
                assert found.mean(p, side) == pytest.approx(true.mean(p, side), rel=0.01), p
            assert found.mean("step_width", side) == pytest.approx(
                true.mean("step_width", side), rel=0.02
            )
            for p in ("stance", "swing", "double_support"):
                assert found.mean(p, side) == pytest.approx(true.mean(p, side), abs=1.0), p


def test_truth_from_markers_is_the_walkers_nominal_gait(trials) -> None:
    """The definitions themselves: heel markers at true contacts give the walker's own
    cadence, speed, stride, step, width and phase fractions."""
    for tr in trials:
        true, nominal = _synth.true_spatiotemporal(tr), tr.truth.nominal()
        for side in ("left", "right"):
            for p in ("cadence", "walking_speed", "stride_length", "step_length"):
                assert true.mean(p, side) == pytest.approx(nominal[p], rel=1e-3), p
            assert true.mean("step_width", side) == pytest.approx(nominal["step_width"], abs=1e-3)
            for p in ("stance", "swing", "double_support"):
                assert true.mean(p, side) == pytest.approx(nominal[p], abs=1e-6), p


def test_table_and_summary_formats(trials) -> None:
    st = _synth.measured_spatiotemporal(trials[0])
    rows = st.rows()
    assert [r["parameter"] for r in rows[::2]] == list(UNITS)
    assert set(rows[0]) == {"parameter", "side", "mean", "sd", "unit", "n_strides"}
    cadence = rows[0]
    assert cadence["unit"] == "steps/min" and cadence["n_strides"] >= 2
    assert 0.0 <= cadence["sd"] < 2.0
    summary = st.summary()
    assert summary["walking_speed"]["unit"] == "m/s"
    assert summary["stance"]["left"]["n"] == len(st.values[("stance", "left")])


def test_one_stride_has_no_sd_and_a_missed_strike_breaks_no_stride() -> None:
    t = np.arange(400) / 100.0
    heel = {
        s: np.column_stack([1000.0 * t, np.full(400, y), 0 * t])
        for s, y in (("left", 50.0), ("right", -50.0))
    }
    gm = _synth.GaitMarkers((heel["left"],), heel, heel, 100.0, {})
    ev = GaitEvents.from_times(
        {("left", "foot_strike"): [0.5, 1.5, 3.5], ("right", "foot_strike"): [1.0, 2.0]}, 100.0
    )
    st = spatiotemporal_parameters(ev, gm)
    assert list(st.values[("stride_time", "left")]) == [1.0]  # 1.5 -> 3.5 hides a strike
    left = next(r for r in st.rows() if r["parameter"] == "cadence" and r["side"] == "left")
    assert left["mean"] == 120.0 and np.isnan(left["sd"]) and left["n_strides"] == 1
    assert st.summary()["cadence"]["left"]["sd"] is None
    assert st.summary()["stance"]["left"] == {"mean": None, "sd": None, "n": 0}
