"""The pelvis' names by the walk and by the paths pieces continue (issue 27, kiss 3
cameras seed 470): the walking direction from enough names, and a sacrum piece named an
ASIS between the sacrum's pieces."""

import numpy as np
import pytest

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.pelvis import settle_pelvis_offsets, walking_direction
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.tracks import make_tracks
from tests.tracking.test_anatomy import LOWER, PIG, walker

#: Fields of the sacrum's three pieces and of the ASIS's two (unseen around the middle
#: sacrum piece), in the synthetic walker's 150 fields.
SACRUM_PIECES = ((0, 50), (60, 80), (90, 150))
ASIS_PIECES = ((0, 55), (85, 150))
#: Names unseen while the middle sacrum piece is (three cameras: the thighs, knees and
#: shanks hidden, the feet and the other ASIS in view).
HIDDEN = ("LTHI", "RTHI", "LKNE", "RKNE", "LTIB", "RTIB")


def test_the_walking_direction_needs_three_names_stepping() -> None:
    """Where one foot alone is held its step is its own (nothing in stance, twice the
    body's in swing), not the body's: no direction there; where three names are held
    the median is the body's, the feet's pace aside."""
    pos = walker(10, 75.0)
    heading = np.radians(75.0)
    forward = np.array([np.cos(heading), np.sin(heading)])
    lone = pos.copy()
    lone[np.arange(len(LOWER)) != LOWER.index("LHEE"), 60:100] = np.nan
    direction = walking_direction(lone)
    assert np.isnan(direction[65:95]).all()
    held = np.isfinite(direction[:, 0])
    unit = direction[held] / np.linalg.norm(direction[held], axis=1, keepdims=True)
    assert np.all(unit @ forward > np.cos(np.radians(20)))


def _sacrum_named_asis(pos: np.ndarray, asis: str) -> tuple[LabelState, np.ndarray, int]:
    """A state whose pieces are the walker's trajectories, the sacrum in three pieces and
    ``asis`` in two, the legs' hidden markers cut where the middle sacrum piece is, all
    named right but the middle sacrum piece, named ``asis``; the right names and that
    piece."""
    i, j = LOWER.index(asis), LOWER.index("SACR")
    gap = SACRUM_PIECES[1]
    cuts = {j: SACRUM_PIECES, i: ASIS_PIECES}
    cuts |= {LOWER.index(n): ((0, gap[0]), (gap[1], pos.shape[1])) for n in HIDDEN}
    spans = [(k, a, b) for k in range(len(LOWER)) for a, b in cuts.get(k, ((0, pos.shape[1]),))]
    field = np.concatenate([np.arange(a, b) for _, a, b in spans])
    piece = np.repeat(np.arange(len(spans)), [b - a for _, a, b in spans])
    xyz = np.concatenate([pos[k, a:b] for k, a, b in spans])
    tracks = make_tracks(field, piece, xyz, xyz, np.zeros(field.size), np.arange(field.size))
    state = LabelState.begin(tracks, LOWER, PIG.template_mm, None, TrackingParams())
    owner = np.empty(tracks.n_tracks, dtype=int)
    owner[tracks.track] = np.array([k for k, _, _ in spans])[piece[tracks.point]]
    middle = int(np.flatnonzero((owner == j) & (tracks.field[state.start] == gap[0]))[0])
    for t, k in enumerate(owner):
        state.name_piece(t, i if t == middle else int(k))
    return state, owner, middle


@pytest.mark.parametrize("asis", ["LASI", "RASI"])
def test_a_sacrum_piece_named_an_asis_between_the_sacrum_s_pieces_takes_the_sacrum(
    asis: str,
) -> None:
    """Kiss 3 seed 470: a first window named the pelvis round, the walk put the long
    pieces right, and a 16-field sacrum piece named by the path it continued kept the
    ASIS's name: with the other ASIS and the feet alone held there, the template's
    distances fitted the ASIS's better by more than the clear ratio (the feet are a
    stride off them). The walk and the paths on both sides (the sacrum's, not the
    ASIS's, a pelvis' width off) give it the sacrum; right names stay so, walking
    backwards too."""
    state, owner, middle = _sacrum_named_asis(walker(10, 75.0), asis)
    assert settle_pelvis_offsets(state)
    np.testing.assert_array_equal(state.label_of, owner)
    for pos in (walker(10, 75.0), walker(10, 75.0)[:, ::-1].copy()):
        right, owner, middle = _sacrum_named_asis(pos, asis)
        right.name_pos[LOWER.index(asis), right.piece(middle)[0]] = np.nan
        right.name_piece(middle, LOWER.index("SACR"))
        assert not settle_pelvis_offsets(right)
        np.testing.assert_array_equal(right.label_of, owner)
