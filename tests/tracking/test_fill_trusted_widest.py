"""The trusted pass's fill of a marker on two segments (kisscal.tracking.fill_trusted
.widest_segment), against truth: an ankle at the joint of a swinging shank (its tibia
marker measured) and a pitching foot (heel and toe measured), hidden for 40 fields (modern
3 cameras seed 430's RANK, hidden from all three cameras for 41 fields, its knee lost
there). The tibia keeps its distance to the ankle best, and rules out the heel and toe
the body's fills then chose: no body fill has donors."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.fill_body import spline_or_body
from kisscal.tracking.fill_trusted import trusted_body, widest_segment
from kisscal.tracking.gap_record import Gap

PARAMS = TrackingParams()
LO, HI = 80, 120
TIB, HEE, TOE, ANK = range(4)


def _leg(n: int = 200) -> np.ndarray:
    """(4, n, 3): tibia, heel, toe and ankle, forward at 1.2 m/s at 100 Hz; the shank
    swings 25 degrees about the ankle, the foot pitches 12 degrees out of phase."""
    t = np.arange(n) / 100.0
    ankle = np.column_stack([1200.0 * t, 10.0 * np.sin(2.0 * t), 80.0 + 30.0 * np.sin(6.0 * t)])

    def turned(local: np.ndarray, angle: np.ndarray) -> np.ndarray:  # about the lab y
        c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
        return (
            np.column_stack(
                [local[0] * c + local[2] * s, 0 * c + local[1], -local[0] * s + local[2] * c]
            )
            + ankle
        )

    shank, foot = 0.45 * np.sin(6.0 * t), 0.2 * np.sin(6.0 * t + 1.5)
    tib = turned(np.array([40.0, 10.0, 200.0]), shank)
    hee = turned(np.array([-70.0, 5.0, -40.0]), foot)
    toe = turned(np.array([150.0, -10.0, -50.0]), foot)
    return np.stack([tib, hee, toe, ankle])


def _gap() -> tuple[Gap, np.ndarray]:
    """The ankle's gap [LO, HI), the foot's markers 0.3 mm noisy, the tibia's 0.1 mm
    (it keeps its distance to the ankle best); and the truth."""
    truth = _leg()
    rng = np.random.default_rng(3)
    dense = (
        truth + rng.normal(0.0, 1.0, truth.shape) * np.array([0.1, 0.3, 0.3, 0.3])[:, None, None]
    )
    dense[ANK, LO:HI] = np.nan
    errors = np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan)
    gap = Gap(dense, ANK, LO, HI, PARAMS, None, None, np.zeros(HI - LO, bool), [], errors=errors)
    return gap, truth


def test_the_body_fills_find_no_donors_for_the_two_segment_marker():
    from kisscal.tracking.bodyfill import distance_sd

    gap, _ = _gap()
    sd = distance_sd(gap.dense[:ANK], gap.dense[ANK][None])[:, 0]
    assert sd.argmin() == TIB and sd.max() < PARAMS.rigid_fill_sd_mm  # rigid to all three
    assert distance_sd(gap.dense[TIB][None], gap.dense[HEE][None])[0, 0] > PARAMS.rigid_fill_sd_mm
    assert not spline_or_body(gap, LO, HI, PARAMS).any()


def test_the_widest_segment_hides_the_tibia_only():
    gap, _ = _gap()
    wide = widest_segment(gap.dense, ANK, LO, HI, PARAMS)
    assert wide is not None
    assert np.isnan(wide[TIB]).all() and np.array_equal(wide[HEE:], gap.dense[HEE:], equal_nan=True)


def test_the_trusted_pass_fills_it_from_the_foot_honestly():
    gap, truth = _gap()
    placed = trusted_body(gap, LO, HI, PARAMS)
    assert placed.all()
    for xyz, f in gap.out:
        assert set(f.donors) <= {HEE, TOE}
        err = np.linalg.norm(xyz - truth[ANK, f.first_field : f.first_field + f.n_fields], axis=1)
        assert np.all(err <= 2.0 * f.expected_error_mm)
        assert np.sqrt(np.mean(err**2)) < PARAMS.ray_rest_max_error_mm


def test_a_marker_of_one_segment_is_left_to_the_body_fills():
    # the heel: the toe and the (hidden) ankle are its segment, the tibia is not rigid to it
    gap, _ = _gap()
    gap.dense[ANK] = _leg()[ANK]
    assert widest_segment(gap.dense, HEE, LO, HI, PARAMS) is None


def test_a_fill_whose_error_was_not_measured_does_not_take_its_donors_errors():
    # kiss 3 seed 430: LANK's two-marker fill, its error unmeasured (NaN), expected 1.6
    # mm from LHEE's spline fill of one field, 4.4 mm RMS off
    from kisscal.tracking.bodyfill import Candidate, GapFill
    from kisscal.tracking.fill_trusted import counted
    from kisscal.tracking.tracks import FILLED_RIGID

    errors = np.zeros((3, 20))
    errors[1, 8] = 1.6
    fill = GapFill(2, 5, 6, FILLED_RIGID, float("nan"), (0, 1))
    assert counted([Candidate(np.zeros((6, 3)), fill, np.nan)], errors) == []
    fill = GapFill(2, 5, 6, FILLED_RIGID, 0.5, (0, 1))
    got = counted([Candidate(np.zeros((6, 3)), fill, np.nan)], errors)
    assert [c.fill.expected_error_mm for c in got] == [1.6]
