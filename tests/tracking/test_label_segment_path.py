"""A foot piece with no rigid partner in view takes the name whose trajectory it
continues, seen from the shank, over the body fit's (labelling.paths.by_segment_path;
modern 3 cameras seed 443: the left toe's last piece, its foot's other markers hidden,
was named the heel by the standing template, 23 identity switches)."""

import numpy as np
import pytest

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.paths import by_segment_path, segment_path
from kisscal.tracking.labelling.pieces import step_from
from kisscal.tracking.labelling.state import LabelState, segment_mask
from kisscal.tracking.tracks import make_tracks
from tests.tracking._data import NAMES, SEGMENTS, gait_truth, template

LANK, LHEE, LTOE = (NAMES.index(n) for n in ("LANK", "LHEE", "LTOE"))
#: The shank's and the foot's segments too, as Plug-in Gait's sets have them.
RIGID = segment_mask(
    NAMES, (*SEGMENTS, ("LTIB", "LANK"), ("LKNE", "LTIB"), ("LHEE", "LTOE"), ("LANK", "LTOE"))
)
#: The left toe's piece after a gap (0.2 s), and where the toe's, the heel's and the
#: ankle's trajectories end before it: as in seed 443, the heel seen last, nearest in time.
PIECE, TOE_END, HEEL_END, ANKLE_END = (120, 150), 110, 117, 100


def _state(seed: int, piece_of: int = LTOE):
    """Every marker one named piece, but the left foot's: the toe seen to :data:`TOE_END`
    and then (unnamed) over :data:`PIECE`, the heel to :data:`HEEL_END`, the ankle to
    :data:`ANKLE_END`; ``piece_of`` is the marker the unnamed piece follows. Returns the
    state and the unnamed piece."""
    truth = gait_truth(200, seed)
    spans = [(m, 0, 200) for m in range(len(NAMES)) if m not in (LANK, LHEE, LTOE)]
    spans += [(LTOE, 0, TOE_END), (LHEE, 0, HEEL_END), (LANK, 0, ANKLE_END), (piece_of, *PIECE)]
    f = np.concatenate([np.arange(lo, hi) for _, lo, hi in spans])
    track = np.concatenate([np.full(hi - lo, k) for k, (_, lo, hi) in enumerate(spans)])
    xyz = np.concatenate([truth[m, lo:hi] for m, lo, hi in spans])
    xyz += np.random.default_rng(seed).normal(0, 0.5, xyz.shape)
    tracks = make_tracks(
        f, track, xyz, np.full(xyz.shape, np.nan), np.zeros(f.size), np.full(f.size, -1)
    )
    state = LabelState.begin(tracks, NAMES, template(), SEGMENTS, TrackingParams())
    for k, (m, _, _) in enumerate(spans[:-1]):
        state.name_piece(k, m)
    return state, len(spans) - 1


def test_step_from_gives_the_trajectory_s_fields_beside_a_piece():
    seen = np.zeros(20, dtype=bool)
    seen[[2, 3, 15, 17]] = True
    assert step_from(seen, 5, 9) == [(3, 5), (15, 9)]
    assert step_from(seen, 0, 1) == [(2, 1)]  # past the start: one side only
    assert step_from(seen, 18, 19) == [(17, 18)]
    assert step_from(np.zeros(20, dtype=bool), 5, 9) == []


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_a_toe_piece_takes_the_toe_s_name_it_continues_not_the_heel_s(seed):
    state, t = _state(seed)
    names = np.array([LHEE, LTOE])
    fields, xyz = state.piece(t)
    # seen from the shank, the piece steps on from the toe's end, not from the heel's
    assert segment_path(state, fields, xyz, names, RIGID).tolist() == [-1, 1]
    assert by_segment_path(state, t, names, RIGID, LHEE) == LTOE
    assert by_segment_path(state, t, names, RIGID, LTOE) == LTOE


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_a_heel_piece_keeps_the_heel_s_name(seed):
    """The heel seen again: the body fit's name is the one it continues, and stays."""
    state, t = _state(seed, piece_of=LHEE)
    names = np.array([LHEE, LTOE])
    assert by_segment_path(state, t, names, RIGID, LHEE) == LHEE


def test_without_a_trajectory_beside_the_piece_the_body_fit_s_name_stands():
    state, t = _state(1)
    state.name_pos[LTOE] = np.nan  # the toe never seen before its piece
    names = np.array([LHEE, LTOE])
    fields, xyz = state.piece(t)
    assert segment_path(state, fields, xyz, names, RIGID)[1] == 0
    assert by_segment_path(state, t, names, RIGID, LHEE) == LHEE
