"""Phase 5b (:mod:`kisscal.tracking.labelling.unseen`): a short piece of a marker whose
name the trial never showed otherwise, named by the template (kiss 3-camera seed 304:
the right thigh seen by two cameras for 15 fields, the right knee and ankle never)."""

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling import label_tracks
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.labelling.unseen import name_unseen
from kisscal.tracking.tracks import make_tracks
from tests.tracking._data import NAMES, SEGMENTS, gait_truth, template

PARAMS = TrackingParams()
THIGH, KNEE, ANKLE = (NAMES.index(n) for n in ("RTHI", "RKNE", "RANK"))
#: Out of view while the thigh is seen, as at the end of seed 304's walk: the body fit
#: from the nearest named markers (the other leg's) misses the thigh by a stride.
AWAY = tuple(NAMES.index(n) for n in ("RASI", "LASI", "RTIB", "LTHI"))


def _trial(seed, short=(150, 165), extra=()):
    """Every marker seen throughout but the right knee and ankle (never), the right
    thigh (only over ``short``) and :data:`AWAY` (all but ``short``); ``extra`` adds
    (marker, offset) pieces, the marker's true path moved, over ``short``.
    Returns the tracks and the true marker of each piece (-1: stray)."""
    truth = gait_truth(200, seed)
    rng = np.random.default_rng(seed)
    whole = [m for m in range(len(NAMES)) if m not in (THIGH, KNEE, ANKLE, *AWAY)]
    pieces = [(m, np.arange(200)) for m in whole]
    pieces += [(m, f) for m in AWAY for f in (np.arange(short[0]), np.arange(short[1], 200))]
    pieces.append((THIGH, np.arange(*short)))
    field, track, xyz, owner = [], [], [], []
    for m, f in pieces:
        field.append(f)
        track.append(np.full(f.size, len(owner)))
        xyz.append(truth[m, f] + rng.normal(0, 0.5, (f.size, 3)))
        owner.append(m)
    for m, offset in extra:
        f = np.arange(*short)
        field.append(f)
        track.append(np.full(f.size, len(owner)))
        xyz.append(truth[m, f] + offset)
        owner.append(-1)
    f = np.concatenate(field)
    tracks = make_tracks(
        f, np.concatenate(track), np.concatenate(xyz), np.full((f.size, 3), np.nan),
        np.zeros(f.size), np.full(f.size, -1),
    )  # fmt: skip
    first = [int(ff[0]) for ff in field]
    order = sorted(range(len(field)), key=lambda t: (first[t], t))
    return tracks, np.asarray(owner)[order]


def _state(tracks, owner):
    """The state with every piece of a marker seen throughout named right."""
    state = LabelState.begin(tracks, NAMES, template(), SEGMENTS, PARAMS)
    for t, m in enumerate(owner):
        if m >= 0 and m != THIGH:
            state.name_piece(t, int(m))
    return state


def test_a_short_piece_takes_the_one_unseen_name_it_fits():
    for seed in range(4):
        tracks, owner = _trial(seed)
        state = _state(tracks, owner)
        assert name_unseen(state)
        assert state.label_of[owner == THIGH].tolist() == [THIGH]


def test_the_whole_labelling_names_the_short_thigh_piece():
    # before phase 5b the piece of seed 0 stayed unnamed (M1), as seed 304's did: the
    # body fit from the other leg put the thigh's name beyond ``label_tolerance_mm``
    for seed in range(4):
        tracks, _ = _trial(seed)
        res = label_tracks(tracks, NAMES, PARAMS, template(), SEGMENTS)
        assert "RTHI" in res.labels and not res.unlabelled
        assert (res.tracks.track == res.labels.index("RTHI")).sum() == 15


def test_a_stray_that_fits_no_unseen_name_stays_unnamed():
    # beside the pelvis, 300 mm out to the right: no name's template distances
    stray = (NAMES.index("RASI"), np.array([0.0, -300.0, 0.0]))
    tracks, owner = _trial(2, extra=[stray])
    state = _state(tracks, owner)
    name_unseen(state)
    assert state.label_of[owner == -1].tolist() == [-1]
    assert state.label_of[owner == THIGH].tolist() == [THIGH]


def test_a_piece_of_a_held_name_is_not_given_an_unseen_one():
    # a second piece on the left ASIS (its own name held): it fits its own name best
    twin = (NAMES.index("LASI"), np.array([0.0, 0.0, 5.0]))
    tracks, owner = _trial(3, extra=[twin])
    state = _state(tracks, owner)
    name_unseen(state)
    assert state.label_of[owner == -1].tolist() == [-1]
