"""The wand route's choice between the wand's calibration and the rods' alone."""

from __future__ import annotations

import numpy as np

from kisscal.session.routes.wand_judge import (
    Judgement,
    LengthEvidence,
    length_evidence,
    paired_errors,
)


def _judgement(wand_mm: np.ndarray, rods_mm: np.ndarray, length_diff: float) -> Judgement:
    length = LengthEvidence(0.5, 0.5, length_diff, 0.01)
    return Judgement(paired_errors(wand_mm, rods_mm), length, 2.0)


def test_the_paired_errors_compare_the_same_markers_only() -> None:
    wand = np.array([0.1, 0.2, np.nan, 0.1])
    rods = np.array([0.2, 0.2, 0.1, np.nan])
    out = paired_errors(wand, rods)
    assert out.markers == 2
    np.testing.assert_allclose(out.wand_rms_mm, np.sqrt((0.01 + 0.04) / 2))
    np.testing.assert_allclose(out.mean_difference_mm2, (0.01 - 0.04) / 2)
    assert out.as_dict()["rods_alone_rms_mm"] == out.rods_alone_rms_mm
    assert paired_errors(wand[:1], rods[:1]).as_dict() == {"markers": 1}


def test_the_wand_is_kept_only_better_on_held_out_markers_and_not_worse_in_length() -> None:
    rng = np.random.default_rng(0)
    rods = rng.uniform(0.05, 0.2, 24)
    for wand, length_diff, want in (
        (0.8 * rods, 0.0, "wand"),  # better on markers, length equal
        (0.8 * rods, 0.015, "wand"),  # length worse within 2 standard errors
        (0.8 * rods, 0.05, "rods"),  # length worse beyond them
        (1.2 * rods, -0.05, "rods"),  # length better, markers worse: the frame moved
    ):
        judgement = _judgement(wand, rods, length_diff)
        assert judgement.kept == want
        verdicts = judgement.as_dict()
        assert verdicts["held_out_rod_markers_rms_mm"]["asks"] == "better"
        assert verdicts["held_out_wand_length_rms_error_mm"]["wand_passes"] == (length_diff <= 0.02)
    # nothing to judge by: the rods' calibration stays
    assert _judgement(rods[:1], rods[:1], 0.0).kept == "rods"
    # markers better, length not measured: the markers decide
    assert Judgement(paired_errors(0.8 * rods, rods), None, 2.0).kept == "wand"


def test_the_length_evidence_is_read_from_the_wand_record() -> None:
    doc = {
        "held_out": {"length_rms_error_mm": 0.4},
        "held_out_rods_alone": {
            "length_rms_error_mm": 0.5,
            "wand_minus_rods": {"mean_difference_mm2": -0.02, "standard_error_mm2": 0.01},
        },
    }
    assert length_evidence(doc) == LengthEvidence(0.4, 0.5, -0.02, 0.01)
    assert length_evidence({"held_out": {}, "held_out_rods_alone": {}}) is None
