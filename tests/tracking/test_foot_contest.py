"""The last contest for each foot's names (:mod:`kisscal.tracking.labelling.feet`)."""

import numpy as np

import kisscal.tracking.labelling.label as label_module
from kisscal.synth.motion import standing_template, walking_trial
from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling.feet import feet_of, score, settle_feet
from kisscal.tracking.labelling.footwalk import ordered_pairs
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.tracks import make_tracks
from tests.tracking._data import NAMES, gait_truth
from tests.tracking.test_labelling_phases import _pieces, _state

INDEX = {n: i for i, n in enumerate(NAMES)}
ANK, HEE, TOE = INDEX["RANK"], INDEX["RHEE"], INDEX["RTOE"]


def _named(tracks, owner):
    """A state with every piece named after its true marker."""
    state = _state(tracks)
    for t, m in enumerate(owner):
        state.name_piece(t, int(m))
    return state


def _rename(state, pieces, names):
    """Pieces ``pieces`` named ``names`` (-1: unnamed) instead of what they hold."""
    for t in pieces:
        state.name_pos[state.label_of[t], state.piece(t)[0]] = np.nan
        state.label_of[t] = -1
    for t, j in zip(pieces, names, strict=True):
        if j >= 0:
            state.name_piece(t, j)


def test_the_naming_convention_gives_each_foot_with_its_shank():
    feet = feet_of(NAMES)
    assert len(feet) == 2
    right = next(f for f in feet if f.toe == TOE)
    assert [NAMES[j] for j in right.names] == ["RANK", "RHEE", "RTOE"]
    assert [NAMES[j] for j in right.shank] == ["RKNE", "RTIB"]
    assert feet_of(("A", "B", "RHEE", "RTOE")) == []  # no shank: no contest


def test_the_score_needs_every_pair_seen_and_charges_a_toe_behind_its_heel():
    """A piece that fits by never being seen with the rest of the foot scores infinite (the
    tennis serve: later pieces of the heel and toe took their names from the whole-trial
    trajectories); a toe trailing its heel costs ``1 / margin``."""
    target = np.array([100.0, 200.0, 50.0])
    dist = np.array([[110.0, 190.0, 50.0], [100.0, np.nan, 50.0]])
    out = score(dist, target, np.array([False, False]), 0.25)
    assert 0 < out[0] < 0.01 and np.isinf(out[1])
    trailing = score(dist[:1], target, np.array([True]), 0.25)
    np.testing.assert_allclose(trailing, 4 * out[0])


def test_a_foot_whose_names_the_match_rotated_gets_them_back():
    """As in a real Vicon walk: the ankle's trajectory named heel, the toe's ankle, the
    heel's unnamed. The distances to the knee and tibia markers and within the foot fit
    the template only with the names back in place; right names stay."""
    tracks, owner = _pieces(gait_truth(200, 3))
    state = _named(tracks, owner)
    assert not settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)
    piece = {m: int(np.flatnonzero(owner == m)[0]) for m in (ANK, HEE, TOE)}
    _rename(state, [piece[ANK], piece[TOE], piece[HEE]], [HEE, ANK, -1])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_heel_and_toe_pieces_named_the_wrong_way_round_are_renamed():
    """A short heel piece named toe, and the toe piece beside it named heel: the walk
    puts the toe ahead."""
    truth = gait_truth(200, 3)
    tracks, owner = _pieces(truth, cuts={HEE: (120, 140), TOE: (120,)})
    state = _named(tracks, owner)
    short = int(np.flatnonzero(owner == HEE)[1])
    late_toe = int(np.flatnonzero(owner == TOE)[1])
    _rename(state, [short, late_toe], [TOE, HEE])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_a_short_ankle_piece_named_heel_while_the_heel_is_unnamed_takes_the_ankle():
    """With three cameras a seven-field ankle piece was fitted to the heel from the body
    while the heel's own piece there was unnamed: its distances to the knee, tibia and
    toe are the ankle's; the heel's piece then takes the heel by its partners."""
    truth = gait_truth(200, 3)
    tracks, owner = _pieces(truth, cuts={ANK: (100, 107), HEE: (95, 115)})
    state = _named(tracks, owner)
    heel = int(np.flatnonzero(owner == HEE)[1])
    short = int(np.flatnonzero(owner == ANK)[1])
    _rename(state, [heel, short], [-1, HEE])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_a_toe_piece_named_heel_beside_the_unnamed_heel_is_renamed_by_the_walk():
    """Three cameras, kiss seed 312: no shank marker named, a 12-field toe piece named
    heel and the heel's own piece beside it unnamed, at the foot's length: the walk puts
    the toe ahead, and the two take their names."""
    truth = gait_truth(200, 3)
    tracks, owner = _pieces(truth, cuts={HEE: (110, 140), TOE: (120, 132)})
    state = _named(tracks, owner)
    for m in (INDEX["RKNE"], INDEX["RTIB"], ANK):
        _rename(state, np.flatnonzero(owner == m).tolist(), [-1] * int(np.sum(owner == m)))
    toe = int(np.flatnonzero(owner == TOE)[1])
    heel = int(np.flatnonzero(owner == HEE)[1])
    _rename(state, [toe, heel], [HEE, -1])
    assert settle_feet(state, state.template)
    assert state.label_of[toe] == TOE and state.label_of[heel] == HEE


def _walk_pieces(truth, spans):
    """Tracks of the pieces ``spans`` ((marker, first field, end field)) of ``truth``
    (0.5 mm noise), and the marker of each piece (in the tracks' numbering)."""
    rng = np.random.default_rng(1)
    field = [np.arange(lo, hi) for _, lo, hi in spans]
    xyz = [truth[m, lo:hi] + rng.normal(0, 0.5, (hi - lo, 3)) for m, lo, hi in spans]
    track = [np.full(f.size, k) for k, f in enumerate(field)]
    f = np.concatenate(field)
    tracks = make_tracks(
        f, np.concatenate(track), np.concatenate(xyz), np.full((f.size, 3), np.nan),
        np.zeros(f.size), np.full(f.size, -1),
    )  # fmt: skip
    order = sorted(range(len(spans)), key=lambda k: (spans[k][1], k))
    return tracks, np.array([spans[k][0] for k in order])


def _named_walk(pieces: dict[str, list[tuple[int, int]]], named: bool = True) -> tuple:
    """The state of a 200-field synthetic walk whose markers are each one piece over the
    whole walk but those of ``pieces`` (name: its pieces' (first, end) fields; none:
    never seen), every piece named its marker's name (unless not ``named``); with the
    marker of each piece and the names' indices."""
    motion = walking_trial(3, 200)
    names = motion.names
    j = {n: k for k, n in enumerate(names)}
    truth = motion.xyz_mm.transpose(1, 0, 2)
    spans = [(m, 0, 200) for m, n in enumerate(names) if n not in pieces]
    spans += [(j[n], lo, hi) for n, runs in pieces.items() for lo, hi in runs]
    tracks, owner = _walk_pieces(truth, spans)
    state = LabelState.begin(
        tracks, names, standing_template(names), motion.segments, TrackingParams()
    )
    for t, m in enumerate(owner if named else ()):
        state.name_piece(t, int(m))
    return state, owner, j


def test_a_heel_and_toe_the_shank_cannot_tell_apart_take_their_names_from_the_walk():
    """Kiss 3 cameras, seed 301, one more true ankle point: a window named the left heel's
    piece toe and the toe's piece heel, with no knee or ankle in their fields. The kiss
    template puts the tibia 264 and 266 mm from heel and toe, so their distances fit
    either way within noise (0.4 against 0.9 mm), and a ratio of such scores must not
    outweigh the walk, which puts the toe ahead in every field."""
    state, owner, j = _named_walk({"LKNE": [], "LANK": [], "LHEE": [(0, 150)], "LTOE": [(0, 50)]})
    settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)  # right names stay
    heel, toe = (int(np.flatnonzero(owner == j[n])[0]) for n in ("LHEE", "LTOE"))
    _rename(state, [heel, toe], [j["LTOE"], j["LHEE"]])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_a_knee_never_seen_does_not_keep_a_heel_and_toe_exchanged():
    """Kiss 3 cameras, seed 301, with nine more true points: the left knee is never seen,
    the window named the heel's trajectory toe and the toe's heel, and the ankle's piece
    stayed unnamed. A distance to a name never seen is unknown, not infinitely wrong: the
    tibia, the ankle's piece and the walk still give the foot its names."""
    state, owner, j = _named_walk(
        {
            "LKNE": [],
            "LTIB": [(0, 60)],
            "LHEE": [(0, 90), (100, 200)],
            "LTOE": [(0, 120), (130, 200)],
        }
    )
    heel, toe = (np.flatnonzero(owner == j[n]).tolist() for n in ("LHEE", "LTOE"))
    ankle = int(np.flatnonzero(owner == j["LANK"])[0])
    _rename(state, [*heel, *toe, ankle], [j["LTOE"]] * 2 + [j["LHEE"]] * 2 + [-1])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_a_foot_the_window_named_the_wrong_way_round_is_settled_before_names_spread(
    monkeypatch,
):
    """Kiss 3 cameras, seed 301, with true hidden points: a window named the left heel
    toe and the toe heel; spreading names then ruled the ankle's name out for an ankle
    piece (its distances to the heel and toe as named are the other way round) and gave
    it the tibia's, the only name left, from a loose body fit; the foot contest at the
    end could not take it back. Settled before names spread, the ankle keeps its name."""
    state, owner, j = _named_walk(
        {"LKNE": [], "LTIB": [(0, 100)], "LANK": [(0, 40), (140, 149)]}, named=False
    )
    ankle = np.flatnonzero(owner == j["LANK"])
    swap = {j["LHEE"]: j["LTOE"], j["LTOE"]: j["LHEE"]}

    def window_with_the_foot_swapped(s):
        s.rich = np.arange(0, 200, 5)
        for t, m in enumerate(owner):
            if t not in ankle:
                s.name_piece(t, swap.get(int(m), int(m)))
        return True

    monkeypatch.setattr(label_module, "match_first_window", window_with_the_foot_swapped)
    assert label_module.name_pieces(state)
    settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_a_foot_s_later_pieces_keep_their_names_when_its_early_pieces_win_them():
    """Kiss 3 cameras, seed 414: the knee never seen, the tibia and ankle early on and in
    a few later fields. The foot's names were held by its later pieces; the contest gave
    them to the early pieces, which fit the template better with the shank there, and
    left the later ones, the same markers at other times, unnamed (the foot named over a
    quarter of the trial). Sharing no field with the winners and rigid to each other at
    the template's distances, toe ahead, they keep their names."""
    state, owner, j = _named_walk(
        {
            "LKNE": [],
            "LTIB": [(0, 60), (115, 127)],
            "LANK": [(0, 60), (115, 127)],
            "LHEE": [(0, 60), (65, 200)],
            "LTOE": [(0, 60), (65, 200)],
        }
    )
    early = [int(np.flatnonzero(owner == j[n])[0]) for n in ("LANK", "LHEE", "LTOE")]
    _rename(state, early, [-1, -1, -1])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_a_toe_piece_named_ankle_takes_the_name_that_fits_best_not_the_first():
    """Modern 3 cameras, seed 464: a ten-field toe piece named ankle where only the knee
    was seen, the heel's own piece there unnamed. As heel it scores far better than as
    ankle (the knee 29 mm farther than the shank's length), as toe better still (within
    4 mm of the template's knee to toe); taking the first name that beat the ankle (the
    heel's, in the foot's order) left the heel's piece unnamed beside it and put ten toe
    samples in the heel's trajectory. The toe piece takes the toe's name, the heel's
    piece the heel's."""
    state, owner, j = _named_walk(
        {
            "LTIB": [(0, 130)],
            "LANK": [(0, 130), (170, 200)],
            "LHEE": [(0, 130), (130, 165), (165, 200)],
            "LTOE": [(0, 140), (150, 160), (170, 200)],
        }
    )
    heel = int(np.flatnonzero(owner == j["LHEE"])[1])
    toe = int(np.flatnonzero(owner == j["LTOE"])[1])
    _rename(state, [heel, toe], [-1, j["LANK"]])
    assert settle_feet(state, state.template)
    assert state.label_of[toe] == j["LTOE"] and state.label_of[heel] == j["LHEE"]


def test_a_heel_named_ankle_and_the_ankle_named_heel_take_their_names_from_the_walk():
    """Kiss 3 cameras, seed 460: the left knee and tibia never seen, the first window
    named the heel's piece ankle (its distances, all across joints, fitted the ankle a
    little better), and a ten-field piece of the ankle then took the heel's name at the
    template's ankle-to-heel length, which is one number either way round; the toe,
    rigid to the heel at the foot's length, fitted no name beside them and stayed
    unnamed. The walk tells: the ankle lies ahead of the heel whatever the foot's pitch."""
    state, owner, j = _named_walk({"LKNE": [], "LTIB": [], "LANK": [(150, 160)]})
    settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)  # right names stay
    heel, toe, ankle = (int(np.flatnonzero(owner == j[n])[0]) for n in ("LHEE", "LTOE", "LANK"))
    _rename(state, [heel, ankle, toe], [j["LANK"], j["LHEE"], -1])
    assert settle_feet(state, state.template)
    np.testing.assert_array_equal(state.label_of, owner)


def test_the_ankle_is_held_between_the_heel_and_the_toe_along_the_walk():
    """The foot contest's order along the walk: in the kiss template the ankle sits 88
    mm of the heel-to-toe line's 226 ahead of the heel, so it is ordered against both
    ends; the toe stays ahead of the heel."""
    right = next(f for f in feet_of(NAMES) if f.toe == TOE)
    pairs = ordered_pairs(standing_template(NAMES), right.names, right.toe, right.heel)
    named = {(NAMES[right.names[a]], NAMES[right.names[b]]) for a, b in pairs}
    assert named == {("RANK", "RHEE"), ("RTOE", "RANK"), ("RTOE", "RHEE")}
    assert [(NAMES[right.names[a]], NAMES[right.names[b]]) for a, b in right.order] == [
        ("RTOE", "RHEE")
    ]


def test_a_toe_named_ankle_with_nothing_named_beside_it_takes_its_name_from_its_heel():
    """Kiss 3 cameras, seed 469: the knee and ankle never seen, the tibia unnamed, the
    first window named the toe's piece ankle from distances across joints (345 identity
    switches), and the heel, in three unnamed pieces, stayed rigid to it at the foot's
    length, which is the heel-to-toe distance and no distance of the ankle's. The two
    take the heel's and the toe's names, the toe ahead along the walk; an ankle named
    right beside its heel keeps its name."""
    heel_pieces = [(0, 60), (70, 130), (140, 200)]
    state, owner, j = _named_walk({"LKNE": [], "LTIB": [], "LANK": [], "LHEE": heel_pieces})
    heels = np.flatnonzero(owner == j["LHEE"]).tolist()
    toe = int(np.flatnonzero(owner == j["LTOE"])[0])
    _rename(state, [*heels, toe], [-1, -1, -1, j["LANK"]])
    assert settle_feet(state, state.template)
    assert state.label_of[toe] == j["LTOE"]
    np.testing.assert_array_equal(state.label_of[heels], j["LHEE"])
    # The same foot without its toe: the ankle named right, the heel unnamed beside it.
    state, owner, j = _named_walk({"LKNE": [], "LTIB": [], "LTOE": [], "LHEE": heel_pieces})
    heels = np.flatnonzero(owner == j["LHEE"]).tolist()
    _rename(state, heels, [-1, -1, -1])
    settle_feet(state, state.template)
    ankle = int(np.flatnonzero(owner == j["LANK"])[0])
    assert state.label_of[ankle] == j["LANK"]
    assert all(state.label_of[h] in (-1, j["LHEE"]) for h in heels)
