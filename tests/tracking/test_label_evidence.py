"""Names the evidence does not support: a foot with fewer markers than names, names
nothing tells apart, a name another fits clearly better (kisscal.tracking.labelling:
feet, anatomy, runnerup), a leg not level with the other, a subject moving otherwise
than forward."""

import numpy as np

from kisscal.markersets import marker_set
from kisscal.synth.motion import walking_trial
from kisscal.tracking import TrackingParams, blend_tracks, track_points
from kisscal.tracking.labelling import label_with_set
from kisscal.tracking.labelling.anatomy import Anatomy, check_anatomy, floor_height
from kisscal.tracking.labelling.feet import (
    _near_ties,
    feet_of,
    naming_choices,
    score,
    settle_feet,
)
from kisscal.tracking.labelling.runnerup import (
    isolated,
    name_margins,
    turned_round,
    uneven_legs,
)
from kisscal.tracking.labelling.sides import doubted
from kisscal.tracking.labelling.state import LabelState

KISS = marker_set("kiss")


def test_naming_choices_leave_names_free_only_when_candidates_are_short():
    full = naming_choices(3, 3)
    assert full.shape == (6, 3) and (full >= 0).all()
    short = naming_choices(2, 3)
    # Two candidates for three names: 3 * 2 ways, each with one name free.
    assert short.shape == (6, 3)
    assert ((short == -1).sum(axis=1) == 1).all()
    assert all(sorted(row[row >= 0].tolist()) == [0, 1] for row in short)


def test_score_counts_only_the_pairs_used():
    dist = np.array([[100.0, 200.0, np.nan]])
    target = np.array([[100.0, 100.0, 50.0]])
    used = np.array([[True, True, False]])
    assert score(dist, target, np.array([False]), 0.25, used)[0] == 0.5  # (0 + 1) / 2
    assert np.isinf(score(dist, target, np.array([False]), 0.25)[0])  # a pair never seen


def test_a_foot_without_its_heel_marker_keeps_ankle_and_toe_names():
    """The walker's left heel marker removed: the left foot has two markers for three
    names; ankle and toe keep their names and the heel name is given to none."""
    m = walking_trial(2, 150, 50.0, path_mm=3500, model="grounded", height_m=1.6, heading_deg=230)
    xyz = m.xyz_mm.copy()
    xyz[:, m.names.index("LHEE")] = np.nan
    f, k = np.nonzero(np.isfinite(xyz[..., 0]))
    pieces = blend_tracks(track_points(f, xyz[f, k], TrackingParams()), TrackingParams())
    found = label_with_set(pieces, KISS, TrackingParams(), 50.0)
    t = found.tracks
    for i, name in enumerate(found.labels):
        if name in m.names:
            rows = t.track == i
            assert np.allclose(t.xyz_mm[rows][0], xyz[t.field[rows][0], m.names.index(name)])
    assert "LANK" in found.labels and "LTOE" in found.labels and "LHEE" not in found.labels


def test_a_heelless_foot_named_one_marker_back_is_given_back_its_names():
    """A foot with no heel marker whose names moved back by one (heel name on the ankle,
    ankle name on the toe, as labelling gave a real Vicon file): the feet contest gives
    ankle and toe their names and leaves the heel name free."""
    m = walking_trial(2, 150, 50.0, path_mm=3500, model="grounded", height_m=1.6, heading_deg=230)
    xyz = m.xyz_mm.copy()
    xyz[:, m.names.index("LHEE")] = np.nan
    f, k = np.nonzero(np.isfinite(xyz[..., 0]))
    pieces = blend_tracks(track_points(f, xyz[f, k], TrackingParams()), TrackingParams())
    template = KISS.scaled(1600.0).template_mm
    state = LabelState.begin(pieces, KISS.names, template, KISS.segments, TrackingParams())
    truth = {}
    for t in range(pieces.n_tracks):
        fields, pts = state.piece(t)
        j = int(np.nanargmin(np.linalg.norm(xyz[fields[0]] - pts[0], axis=1)))
        truth[t] = m.names[j]
    shifted = {"LANK": "LHEE", "LTOE": "LANK"}
    for t, name in truth.items():
        state.name_piece(t, KISS.names.index(shifted.get(name, name)))
    assert settle_feet(state, template)
    got = {t: KISS.names[j] for t, j in enumerate(state.label_of) if j >= 0}
    assert all(got.get(t) == name for t, name in truth.items() if name in ("LANK", "LTOE"))
    assert KISS.names.index("LHEE") not in state.label_of


def test_wrist_bar_ends_are_twins():
    full = marker_set("plug-in-gait-full")
    a = Anatomy.of_set(full)
    assert {(a.names[i], a.names[j]) for i, j in a.twins} == {("LWRA", "LWRB"), ("RWRA", "RWRB")}
    assert Anatomy.of_set(KISS).twins == ()


def test_a_leg_named_one_marker_up_is_clearly_beaten():
    """The true names of a walk are not beaten by another name by 4 % of stature; the
    thigh's name on the knee and the knee's on the ankle are."""
    m = walking_trial(1, 150, 50.0, path_mm=3500, model="grounded", heading_deg=300)
    pos = m.xyz_mm.transpose(1, 0, 2)[[m.names.index(n) for n in KISS.names]]
    anatomy = Anatomy.of_set(KISS)
    deficit = TrackingParams().name_deficit_fraction * np.ptp(KISS.template_mm[:, 2])

    def margins(p):
        return name_margins(p, KISS.template_mm, anatomy.heights_mm, floor_height(p, anatomy))

    assert np.nanmin(margins(pos)) > -deficit
    thigh, knee, ankle = (KISS.names.index(n) for n in ("LTHI", "LKNE", "LANK"))
    shifted = pos.copy()
    shifted[thigh], shifted[knee], shifted[ankle] = pos[knee], pos[ankle], np.nan
    got = margins(shifted)
    assert got[thigh] < -deficit and got[knee] < -deficit


def test_a_name_a_free_name_fits_better_is_doubted():
    """With the thigh markers' names free (no trajectory holds them), a walk's true names
    lose to none of them by ``free_deficit_fraction`` of stature; a thigh marker named
    tibia, its tibia marker unnamed, loses clearly to the free thigh name."""
    m = walking_trial(1, 150, 50.0, path_mm=3500, model="grounded", heading_deg=300)
    pos = m.xyz_mm.transpose(1, 0, 2)[[m.names.index(n) for n in KISS.names]]
    anatomy = Anatomy.of_set(KISS)
    limit = TrackingParams().free_deficit_fraction * np.ptp(KISS.template_mm[:, 2])
    thigh, tibia = KISS.names.index("LTHI"), KISS.names.index("LTIB")

    def margins(p):
        args = (p, KISS.template_mm, anatomy.heights_mm, floor_height(p, anatomy))
        return name_margins(*args, anatomy.pairs, among_free=True)

    free = pos.copy()
    free[[thigh, KISS.names.index("RTHI")]] = np.nan
    assert np.nanmin(margins(free)) > -limit
    shifted = free.copy()
    shifted[tibia] = pos[thigh]
    assert margins(shifted)[tibia] < -limit
    # With every name held nothing is free to weigh.
    assert np.isnan(margins(pos)).all()


def test_a_name_alone_among_its_free_neighbours_is_doubted_by_any_margin():
    """A full-body set on a trial without arms: the true names have their template
    neighbours around them and are not doubted, however little the free deficit asked;
    a thigh marker named finger (the thigh's name free, the knee's held) is the only
    name of its hand and is doubted although the free deficit asked is out of reach.
    Without the knee and tibia markers too the free thigh name's group is absent as
    well, and nothing says the finger's name strayed from it."""
    full = marker_set("plug-in-gait-full")
    t = full.template_mm
    fields = np.arange(100)
    # Walking along x at 1.2 m/s (50 Hz), the body bobbing 20 mm: distances as the template's.
    shift = np.c_[24.0 * fields, np.zeros(100), 20.0 * np.sin(fields / 8.0)]
    pos = t[:, None, :] + shift[None]
    arms = [
        full.names.index(n)
        for n in full.names
        if n[1:] in ("SHO", "UPA", "ELB", "FRM", "WRA", "WRB", "FIN")
    ]
    pos[arms] = np.nan
    anatomy = Anatomy.of_set(full)
    params = TrackingParams(name_deficit_fraction=1.0, free_deficit_fraction=1.0)
    assert not isolated(pos, t).any()
    assert not doubted(pos, anatomy, t, params).any()
    thigh, finger = full.names.index("RTHI"), full.names.index("RFIN")
    shifted = pos.copy()
    shifted[finger], shifted[thigh] = pos[thigh], np.nan
    assert np.flatnonzero(isolated(shifted, t)).tolist() == [finger]
    assert np.flatnonzero(doubted(shifted, anatomy, t, params)).tolist() == [finger]
    shifted[[full.names.index(n) for n in ("RKNE", "RTIB")]] = np.nan
    assert not doubted(shifted, anatomy, t, params)[finger]


def test_a_head_whose_front_names_went_to_its_back_markers_is_turned_round():
    """A full-body set walking along x: the head's back markers hold the forehead's names,
    the forehead's markers are unnamed and the back names free; the unnamed markers move
    rigidly with the named ones ahead of them, so the front names are doubted. Named the
    right way (the back markers unnamed behind the front names), nothing is."""
    full = marker_set("plug-in-gait-full")
    t = full.template_mm
    fields = np.arange(100)
    shift = np.c_[24.0 * fields, np.zeros(100), 20.0 * np.sin(fields / 8.0)]
    pos = t[:, None, :] + shift[None]
    front = [full.names.index(n) for n in ("LFHD", "RFHD")]
    back = [full.names.index(n) for n in ("LBHD", "RBHD")]
    forward = np.tile([1.0, 0.0], (100, 1))
    args = (Anatomy.of_set(full).ahead, t, forward, TrackingParams().min_side_confidence)
    right = pos.copy()
    right[back] = np.nan
    assert not turned_round(right, pos[back], *args).any()
    turned = right.copy()
    turned[front] = pos[back]
    assert np.flatnonzero(turned_round(turned, pos[front], *args)).tolist() == front


def test_a_leg_named_one_marker_down_is_not_level_with_the_other():
    m = walking_trial(1, 150, 50.0, path_mm=3500, model="grounded", heading_deg=300)
    pos = m.xyz_mm.transpose(1, 0, 2)[[m.names.index(n) for n in KISS.names]]
    a = Anatomy.of_set(KISS)
    assert not uneven_legs(pos, a.heights_mm, a.pairs, a.front + a.back).any()
    thigh, knee, tibia = (KISS.names.index(n) for n in ("RTHI", "RKNE", "RTIB"))
    shifted = pos.copy()
    shifted[thigh], shifted[knee], shifted[tibia] = pos[knee], pos[tibia], np.nan
    got = {
        a.names[i]
        for i in np.flatnonzero(uneven_legs(shifted, a.heights_mm, a.pairs, a.front + a.back))
    }
    assert {"RTHI", "LTHI", "RKNE", "LKNE"} <= got


def test_foot_namings_within_a_near_tie_are_doubted():
    """Two ways of naming a foot score within FOOT_TIE: the names they give differently
    are doubtful, the name they agree on is not."""
    m = walking_trial(2, 150, 50.0, path_mm=3500, model="grounded", height_m=1.6, heading_deg=230)
    f, k = np.nonzero(np.isfinite(m.xyz_mm[..., 0]))
    pieces = blend_tracks(track_points(f, m.xyz_mm[f, k], TrackingParams()), TrackingParams())
    state = LabelState.begin(pieces, KISS.names, KISS.template_mm, KISS.segments, TrackingParams())
    foot = feet_of(KISS.names)[0]
    choices = np.array([[0, 1, 2], [1, 0, 2], [2, 1, 0]])
    _near_ties(state, foot, choices, np.array([1.0, 1.1, 2.0]), choices[0], 1.0)
    assert state.doubtful == {int(foot.names[0]), int(foot.names[1])}


def test_a_subject_moving_otherwise_than_forward_faces_where_the_pelvis_does():
    """A standing body carried about in random directions (a tennis serve's steps): the
    direction of travel is no forward, the pelvis' is, and every left name stays left of
    its right partner."""
    m = walking_trial(1, 150, 50.0, path_mm=3500, model="grounded", heading_deg=0)
    still = m.xyz_mm.transpose(1, 0, 2)[[m.names.index(n) for n in KISS.names]][:, :1]
    rng = np.random.default_rng(3)
    steps = np.repeat(rng.normal(size=(12, 2)), 25, axis=0)  # a new direction every 0.5 s
    steps = 12.0 * steps / np.linalg.norm(steps, axis=1, keepdims=True)  # 600 mm/s
    path = np.c_[np.cumsum(steps, axis=0), np.zeros(len(steps))]
    pos = still + path[None]
    anatomy = Anatomy.of_set(KISS)
    check = check_anatomy(pos, anatomy, 50.0)
    assert check.forward == "pelvis"
    assert np.nanmin(check.confidence) > TrackingParams().min_side_confidence
