"""A foot's heel and toe names judged by their order along the walk
(kisscal/tracking/labelling/footorder.py, issue 26)."""

import numpy as np
import pytest

from kisscal.tracking.labelling.anatomy import Anatomy
from kisscal.tracking.labelling.footorder import out_of_order_feet
from tests.tracking.markerset_acceptance import LOWER, walker_trial
from tests.tracking.test_label_partial import FULL, _labelling

RIGHT = {n: n for n in LOWER if n in FULL.names}


def _doubted(truth: np.ndarray, held: dict[str, str], height_mm: float) -> tuple[str, ...]:
    scaled = FULL.scaled(height_mm)
    return out_of_order_feet(_labelling(truth, held), scaled, Anatomy.of_set(scaled), 50.0)


@pytest.mark.parametrize(
    "seed, height_m, fitted_mm", [(2, 1.0, 1450.0), (3, 1.2, 1200.0), (5, 1.8, 1800.0)]
)
def test_a_foot_named_one_marker_along_is_doubted_and_a_right_foot_is_not(
    seed, height_m, fitted_mm
):
    truth, _, _, _ = walker_trial(seed, height_m, 140.0, 0.8, 50.0)
    assert _doubted(truth, RIGHT, fitted_mm) == ()
    # As the 1.0 m child of seed 2 was named with the re-tracking cut: the heel's name on
    # the ankle marker, the heel marker unnamed. Foot markers stay rigid whatever their
    # names; the heel marker lies behind the one named heel.
    heel_on_ankle = {n: m for n, m in RIGHT.items() if n not in ("RHEE", "RANK")}
    assert _doubted(truth, heel_on_ankle | {"RHEE": "RANK"}, fitted_mm) == ("RHEE",)
    # The toe's name on the ankle marker, the toe marker unnamed ahead of it.
    toe_on_ankle = {n: m for n, m in RIGHT.items() if n not in ("LTOE", "LANK")}
    assert _doubted(truth, toe_on_ankle | {"LTOE": "LANK"}, fitted_mm) == ("LTOE",)


def test_a_foreign_forefoot_marker_a_little_ahead_of_the_toe_does_not_doubt_it():
    # As walking5's first metatarsal head lies 21 mm ahead of the second's, which takes
    # the toe's name: a marker rigid to the foot a tenth of its length ahead of the toe.
    truth, _, _, _ = walker_trial(5, 1.8, 140.0, 0.8, 50.0)
    toe, heel = (truth[LOWER.index(n)] for n in ("RTOE", "RHEE"))
    extra = np.concatenate([truth, (toe + 0.1 * (toe - heel))[None]])
    assert _doubted(extra, RIGHT, 1800.0) == ()
    # A whole gap ahead, as the toe marker is when the toe's name is on the ankle's.
    beyond = np.concatenate([truth, (toe + 0.5 * (toe - heel))[None]])
    assert _doubted(beyond, RIGHT, 1800.0) == ("RTOE",)


def test_without_a_forward_direction_nothing_is_doubted():
    # Standing still, with no pelvis back marker of the set (SACR is not one of the full
    # body set's): the only forward left is the feet's own, which the names give.
    truth, _, _, _ = walker_trial(2, 1.0, 140.0, 0.8, 50.0)
    still = np.repeat(truth[:, :1], truth.shape[1], axis=1)
    heel_on_ankle = {n: m for n, m in RIGHT.items() if n not in ("RHEE", "RANK")}
    assert _doubted(still, heel_on_ankle | {"RHEE": "RANK"}, 1450.0) == ()
