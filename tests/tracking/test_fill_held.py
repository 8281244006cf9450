"""A tibia hidden while the ankle, its donor, is pulled off in one field by a merged blob:
the body fill kept where its donors hold (kisscal.tracking.fill_held) against truth."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_held import out_of_shape_fields
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.tracks import MEASURED, make_tracks
from tests.tracking.test_fill_neighbour_hinge import _leg

PARAMS = TrackingParams()
GAP = slice(100, 130)
PULLED = 112
HOLE = [114, 115]


def _hidden_tibia(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Knee, tibia, ankle, heel, toe (:func:`_leg`), the tibia hidden in :data:`GAP`,
    the ankle pulled 10 mm at :data:`PULLED` (its blob merged with another
    marker's image): the dense positions and the truth."""
    xyz, truth = _leg(seed)
    xyz[1, GAP] = np.nan
    xyz[2, PULLED] += [6.0, 0.0, 8.0]
    return xyz, truth


def _tracks(dense: np.ndarray):
    track, field = np.nonzero(np.isfinite(dense[:, :, 0]))
    n = track.size
    return make_tracks(
        field,
        track,
        dense[track, field],
        np.full((n, 3), np.nan),
        np.full(n, MEASURED),
        np.arange(n),
    )


def test_the_pulled_ankle_is_out_of_shape_in_its_field_alone():
    dense, _ = _hidden_tibia(0)
    flagged = out_of_shape_fields(dense, 1, GAP.start, GAP.stop, PARAMS)
    assert np.array_equal(np.argwhere(flagged), [[2, PULLED - GAP.start]])


def test_a_tibia_whose_ankle_is_pulled_in_one_field_is_filled_in_the_others():
    # the hinge about knee and ankle was refused for the whole gap (the ankle out of
    # shape in one field, two donors): nothing filled the tibia
    for seed in (0, 1):
        dense, truth = _hidden_tibia(seed)
        out, _ = fill_gaps_logged(_tracks(dense), PARAMS)
        rows = (out.track == 1) & (out.field >= GAP.start) & (out.field < GAP.stop)
        fields = out.field[rows]
        assert np.setdiff1d(np.arange(GAP.start, GAP.stop), fields).tolist() in ([], [PULLED])
        err = np.linalg.norm(out.xyz_mm[rows] - truth[1, fields], axis=1)
        assert err[fields != PULLED].max() < 3.0


def test_a_heel_hidden_while_the_toe_misses_two_fields_is_filled_in_the_others():
    # the toe's own spline fills its two fields, which the body does not read: its
    # fills found one donor (the ankle) through the gap and left the heel open
    spare = spare_blobs([], [], np.zeros((0, 2)), [[1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1e-3]])
    for seed in (0, 1):
        dense, truth = _leg(seed)
        dense[3, GAP] = np.nan
        dense[4, HOLE] = np.nan
        out, fills = fill_gaps_logged(_tracks(dense), PARAMS, spare)
        rows = (out.track == 3) & (out.field >= GAP.start) & (out.field < GAP.stop)
        assert np.array_equal(out.field[rows], np.setdiff1d(np.arange(GAP.start, GAP.stop), HOLE))
        err = np.linalg.norm(out.xyz_mm[rows] - truth[3, out.field[rows]], axis=1)
        assert err.max() < 2.5
        # true to its expected error
        expected = max(g.expected_error_mm for g in fills if g.track == 3)
        assert np.sqrt(np.mean(err**2)) <= 2.0 * expected
