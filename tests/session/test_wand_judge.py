"""The wand route's choice between the wand's calibration and the rods' alone."""

from __future__ import annotations

import numpy as np

from kisscal.session.routes.wand_judge import judges, kept, paired_errors


def _check(wand_mm: np.ndarray, rods_mm: np.ndarray, length_diff: float) -> dict:
    return {
        "held_out_rod_markers": paired_errors(wand_mm, rods_mm),
        "wand_held_out": {"length_rms_error_mm": 0.5},
        "wand_held_out_rods_alone": {
            "length_rms_error_mm": 0.5,
            "wand_minus_rods": {"mean_difference_mm2": length_diff, "standard_error_mm2": 0.01},
        },
    }


def test_the_paired_errors_compare_the_same_markers_only() -> None:
    wand = np.array([0.1, 0.2, np.nan, 0.1])
    rods = np.array([0.2, 0.2, 0.1, np.nan])
    out = paired_errors(wand, rods)
    assert out["markers"] == 2
    np.testing.assert_allclose(out["wand_rms_mm"], np.sqrt((0.01 + 0.04) / 2))
    np.testing.assert_allclose(out["mean_difference_mm2"], (0.01 - 0.04) / 2)
    assert paired_errors(wand[:1], rods[:1]) == {"markers": 1}


def test_the_wand_is_kept_only_better_on_held_out_markers_and_not_worse_in_length() -> None:
    rng = np.random.default_rng(0)
    rods = rng.uniform(0.05, 0.2, 24)
    for wand, length_diff, want in (
        (0.8 * rods, 0.0, "wand"),  # better on markers, length equal
        (0.8 * rods, 0.015, "wand"),  # length worse within 2 standard errors
        (0.8 * rods, 0.05, "rods"),  # length worse beyond them
        (1.2 * rods, -0.05, "rods"),  # length better, markers worse: the frame moved
    ):
        check = _check(wand, rods, length_diff)
        check["judges"] = judges(check, 2.0)
        assert kept(check) == want
    # nothing to judge by: the rods' calibration stays
    assert kept({"judges": judges(_check(rods[:1], rods[:1], 0.0), 2.0)}) == "rods"
