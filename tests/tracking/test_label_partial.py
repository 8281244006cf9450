"""A part of a marker set: its stature judged by the rigid segments its names hold
(kisscal/tracking/labelling/partial.py, issue 26)."""

import numpy as np
import pytest

from kisscal.markersets import marker_set
from kisscal.tracking import TrackingParams, build_trajectories
from kisscal.tracking.labelling.partial import MIN_SEGMENT_GAIN, segment_score
from kisscal.tracking.labelling.state import segment_mask
from tests.tracking.markerset_acceptance import LOWER, walker_trial, wrong_labels

FULL = marker_set("plug-in-gait-full")
#: A leg's names shifted up by one marker (the thigh's name on the ASIS, the knee's on
#: the thigh marker, ...), as a part fitted at a wrong stature named 2198928's legs.
SHIFTED = {
    f"{s}{a}": f"{s}{b}"
    for s in "LR"
    for a, b in (("THI", "ASI"), ("KNE", "THI"), ("TIB", "KNE"), ("ANK", "TIB"), ("HEE", "ANK"))
}


def _name_pos(truth: np.ndarray, held: dict[str, str]) -> np.ndarray:
    """Trajectories per name of the full set: name -> the true marker it is given."""
    pos = np.full((len(FULL.names), truth.shape[1], 3), np.nan)
    for name, marker in held.items():
        pos[FULL.index(name)] = truth[LOWER.index(marker)]
    return pos


def test_right_names_hold_more_segments_than_names_shifted_along_the_legs():
    truth, _, _, _ = walker_trial(3, 1.0, 140.0, 0.8, 50.0)
    rigid = segment_mask(FULL.names, FULL.segments)
    template = FULL.scaled(1000.0).template_mm
    right = {n: n for n in LOWER if n in FULL.names}
    held, broken, _ = segment_score(_name_pos(truth, right), template, rigid)
    # Pelvis (LASI-RASI), two thighs, two shanks, two feet: all rigid in the walk.
    assert (held, broken) == (7, 0)
    shifted = {n: SHIFTED.get(n, n) for n in right}
    s_held, s_broken, _ = segment_score(_name_pos(truth, shifted), template, rigid)
    # The thigh's name on the ASIS breaks the thigh, the ankle's on the tibia the shank.
    assert s_broken >= 2 and (held - broken) - (s_held - s_broken) >= MIN_SEGMENT_GAIN


@pytest.mark.slow
def test_a_childs_lower_body_named_from_the_full_body_set_gets_its_legs_right():
    # The lower body of a 0.9 m child is a part of the full-body set; stood on the floor it
    # fitted the adult bound, 1.40 m, and its legs' names were shifted up by one marker.
    truth, _, field, xyz = walker_trial(4, 0.9, 140.0, 0.8, 50.0)
    res = build_trajectories(field, xyz, TrackingParams(), marker_set=FULL, rate_hz=50.0)
    wrong = wrong_labels(res, truth, LOWER)
    # SACR is no marker of the full-body set (it has LPSI and RPSI).
    assert [w for w in wrong if w[1] != "SACR"] == []
    assert abs(res.labelling.height_mm - 900.0) <= 100.0
    # The stature overrules the floor fit: nothing is certain, a wrong name never silent.
    unnamed = set(res.labelling.unlabelled)
    named = {label for t, label in enumerate(res.labels) if t not in unnamed}
    assert named and set(res.labelling.flagged) == named
