"""A marker placed far from the template's place, named by the segment it stays rigid
with (:func:`kisscal.tracking.labelling.unseen.name_by_segment`; issue 26: Walking 02's
toe 225 mm from its heel where the template has 123 mm, its tibia marker 287 mm above
the ankle where it has 173 mm, each left unnamed)."""

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.learned import name_from_trial
from kisscal.tracking.labelling.spread import spread
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.labelling.unseen import name_by_segment, name_unseen
from kisscal.tracking.tracks import make_tracks
from tests.tracking._data import NAMES, SEGMENTS, gait_truth, template

PARAMS = TrackingParams()
TIBIA, ANKLE, LTOE = (NAMES.index(n) for n in ("RTIB", "RANK", "LTOE"))
#: The shanks' and feet's segments too, as Plug-in Gait's sets have them.
SETS = (*SEGMENTS, ("RTIB", "RANK"), ("LTIB", "LANK"), ("RHEE", "RTOE"), ("LHEE", "LTOE"))


def _state(seed, stray=None):
    """Every marker but the left toe (never seen) as one piece, all named right but the
    right tibia marker; the template's right tibia marker 130 mm above the subject's
    (beyond ``label_tolerance_mm`` from the body fit). ``stray``: a piece kept at that
    offset from the right ankle marker. Returns the state and the tibia marker's piece."""
    truth = gait_truth(200, seed)
    rng = np.random.default_rng(seed)
    markers = [m for m in range(len(NAMES)) if m != LTOE]
    paths = [truth[m] for m in markers]
    if stray is not None:
        paths.append(truth[ANKLE] + stray)
    f = np.tile(np.arange(200), len(paths))
    xyz = np.concatenate(paths) + rng.normal(0, 0.5, (f.size, 3))
    track = np.repeat(np.arange(len(paths)), 200)
    tracks = make_tracks(
        f, track, xyz, np.full((f.size, 3), np.nan), np.zeros(f.size), np.full(f.size, -1)
    )
    placed = template()
    placed[TIBIA] += [0.0, 0.0, 130.0]
    state = LabelState.begin(tracks, NAMES, placed, SETS, PARAMS)
    state.rich = np.arange(0, 200, 10)
    for t, m in enumerate(markers):
        if m != TIBIA:
            state.name_piece(t, m)
    return state, markers.index(TIBIA)


def test_a_piece_rigid_with_its_segment_takes_the_name_the_template_misplaces():
    for seed in range(3):
        state, tibia = _state(seed)
        spread(state)
        name_from_trial(state)
        name_unseen(state)
        assert state.label_of[tibia] == -1  # the template's distances fit no name
        assert name_by_segment(state)
        assert state.label_of[tibia] == TIBIA


def test_two_pieces_rigid_with_the_segment_leave_its_name_free():
    # another set's marker beside the ankle (a malleolus'): which of the two is the
    # tibia marker is not known
    state, tibia = _state(1, stray=np.array([40.0, -30.0, 20.0]))
    assert not name_by_segment(state)
    assert state.label_of[tibia] == -1 and state.label_of[-1] == -1
