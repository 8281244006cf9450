"""Pieces of a leg seen early in the trial, apart from the names the first window gave
(labelling.spread.rematch and labelling.groups.name_groups), on pieces cut from the
true walk of kiss 3-camera seed 368 as its reconstruction cut them."""

import numpy as np

from kisscal.synth.plan import plan_session
from kisscal.synth.presets import synth_options
from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.groups import name_groups
from kisscal.tracking.labelling.spread import rematch
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.labelling.window import first_centre, window_fields
from kisscal.tracking.tracks import make_tracks

#: (name, first field, last field) of the pieces of at least 10 fields.
PIECES = """LHEE 25 399 LTOE 0 373 LASI 0 259 LTHI 118 373 SACR 155 397 RHEE 168 356
LANK 213 399 RTOE 174 349 LKNE 214 371 LANK 13 155 LTIB 27 168 RTOE 0 136 RASI 242 360
LKNE 72 181 RASI 28 120 LASI 283 361 LTIB 187 245 LTIB 294 349 RASI 140 192 RTHI 28 73
RHEE 0 41 RANK 11 50 RTIB 4 39 SACR 46 81 LTHI 59 92 LTHI 0 25 RHEE 134 156 RTIB 127 148
RTHI 319 338 LKNE 0 17 RHEE 81 98 LTIB 380 395 RTIB 337 348 RANK 338 348 SACR 108 117
RTHI 150 159""".split()


def _before_phase_3():
    """The state as the first window and spreading left it (every piece named right but
    the right leg's before field 160), each piece's true name, and those left."""
    plan = plan_session(synth_options("kiss", 368, fields=400, n_cameras=3))
    truth, names = plan.trials["walk01"].xyz_mm, plan.marker_names
    spec = [(names.index(n), int(a), int(b) + 1) for n, a, b in np.reshape(PIECES, (-1, 3))]
    f = np.concatenate([np.arange(lo, hi) for _, lo, hi in spec])
    t = np.concatenate([np.full(hi - lo, k) for k, (_, lo, hi) in enumerate(spec)])
    xyz = np.concatenate([truth[lo:hi, j] for j, lo, hi in spec])
    xyz += np.random.default_rng(0).normal(0, 0.5, xyz.shape)
    tracks = make_tracks(f, t, xyz, np.full(xyz.shape, np.nan), np.zeros(f.size), np.arange(f.size))
    params = TrackingParams()
    state = LabelState.begin(tracks, names, plan.template_mm, plan.segments, params)
    # make_tracks numbers pieces by first field
    owner = np.array([spec[k][0] for k in sorted(range(len(spec)), key=lambda k: spec[k][1])])
    right = np.isin(owner, [names.index(n) for n in ("RTHI", "RTIB", "RANK", "RHEE", "RTOE")])
    left = right & np.array([state.piece(k)[0][0] < 160 for k in range(owner.size)])
    for k in np.flatnonzero(~left):
        state.name_piece(int(k), int(owner[k]))
    centre = first_centre(state)
    state.rich = window_fields(state.present, centre, state.window, params.label_fields)
    state.fit_rms = 121.3  # the first window's in the trial (judges shorter windows)
    return state, owner, left


def test_a_window_does_not_name_a_foot_marker_against_the_trial_s_distances():
    state, owner, _ = _before_phase_3()
    rematch(state)
    named = state.label_of >= 0
    # Main named the right toe's 137 fields RKNE, a name no piece held (137 switches).
    np.testing.assert_array_equal(state.label_of[named], owner[named])


def test_a_leg_s_pieces_linked_by_its_lengths_are_named_together():
    state, owner, left = _before_phase_3()
    name_groups(state)
    named = state.label_of >= 0
    np.testing.assert_array_equal(state.label_of[named], owner[named])
    # The toe (0-136), its heel's two pieces (0-41, 81-98), the ankle and the tibia:
    # main named none of them; the thigh (28-73) follows by spreading.
    first = np.array([state.piece(k)[0][0] for k in range(owner.size)])
    assert np.all(named[left & (first < 100)])
