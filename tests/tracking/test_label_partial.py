"""A part of a marker set: its stature judged by the rigid segments its names hold
(kisscal/tracking/labelling/partial.py, issue 26)."""

from pathlib import Path

import numpy as np
import pytest

from kisscal.markersets import marker_set
from kisscal.tracking import TrackingParams, build_trajectories
from kisscal.tracking.labelling.partial import MIN_SEGMENT_GAIN, segment_score, unvouched
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.state import segment_mask
from kisscal.tracking.labelling.subject import partial_height
from kisscal.tracking.params import reconstructed_points
from kisscal.tracking.tracks import make_tracks
from tests.tracking.markerset_acceptance import LOWER, walker_trial, wrong_labels

FULL = marker_set("plug-in-gait-full")
FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "real"
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


def _labelling(truth: np.ndarray, held: dict[str, str]) -> Labelling:
    """A labelling of the true markers (one trajectory each, all measured) giving each
    name of ``held`` to the true marker it maps to; the other markers unnamed."""
    n, n_fields = truth.shape[:2]
    field = np.tile(np.arange(n_fields), n)
    track = np.repeat(np.arange(n), n_fields)
    xyz = truth.reshape(-1, 3)
    tracks = make_tracks(field, track, xyz, xyz, np.zeros(field.size, int), np.arange(field.size))
    name_of = {LOWER.index(marker): name for name, marker in held.items()}
    labels = tuple(name_of.get(t, f"M{t}") for t in range(n))
    unlabelled = tuple(t for t in range(n) if t not in name_of)
    return Labelling(tracks, labels, True, unlabelled, (), 0.0)


@pytest.mark.parametrize("seed, height_m", [(3, 1.0), (1, 1.2), (5, 1.6)])
def test_the_segments_vouch_for_right_names_and_not_for_names_shifted_along_the_legs(
    seed, height_m
):
    truth, _, _, _ = walker_trial(seed, height_m, 140.0, 0.8, 50.0)
    right = {n: n for n in LOWER if n in FULL.names}
    assert unvouched(_labelling(truth, right), FULL) == ()
    # A trial without the heel and tibia markers: the toe's and ankle's names, right,
    # have no segment partner and no rigid unnamed neighbour, so nothing doubts them.
    absent = truth.copy()
    absent[[LOWER.index(n) for n in ("LHEE", "LTIB")]] = np.nan
    fewer = {n: m for n, m in right.items() if n not in ("LHEE", "LTIB")}
    assert unvouched(_labelling(absent, fewer), FULL) == ()
    # As the 1.0 m child of seed 3 fitted at 1.45 m was named: the left knee's name on
    # the thigh marker (the thigh's name given to none), the right leg shifted up from
    # the left ASIS; the shanks and feet right.
    wrong = {"LKNE": "LTHI", "RTHI": "LASI", "RKNE": "RTHI"}
    part = {n: n for n in ("LTIB", "LANK", "LHEE", "LTOE", "RTIB", "RANK", "RHEE", "RTOE")}
    assert set(wrong) <= set(unvouched(_labelling(truth, part | wrong), FULL))
    # Every leg name shifted up one marker: the thigh's and knee's names (on the ASIS and
    # the thigh marker) break the thigh. Lower down rigidity cannot tell: the knee and
    # ankle markers sit on their joint's axis, so the shank's names on the knee and
    # tibia markers, or the foot's on the ankle and toe markers, keep their distance.
    shifted = {n: SHIFTED.get(n, n) for n in right}
    thighs = {f"{s}{m}" for s in "LR" for m in ("THI", "KNE")}
    assert thighs <= set(unvouched(_labelling(truth, shifted), FULL))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("height_m", [1.0, 1.1, 1.2])
def test_a_childs_lower_body_fitted_above_the_bound_gets_no_silent_wrong_name(seed, height_m):
    # A 1.0-1.2 m child's lower body named from the full-body set fits 1.45-1.75 m, away
    # from the 1.40 m bound the segments judge, and its legs' names shift up a marker.
    truth, _, field, xyz = walker_trial(seed, height_m, 140.0, 0.8, 50.0)
    res = build_trajectories(field, xyz, TrackingParams(), marker_set=FULL, rate_hz=50.0)
    wrong = wrong_labels(res, truth, LOWER)
    assert [w for w in wrong if w[0] not in res.labelling.flagged] == []


def test_a_set_crowded_by_another_sets_markers_is_not_taken_for_the_whole_set():
    """pyCGM's Movement_trial (fixtures/real/pycgm/: its first second): Plug-in Gait's 39
    markers and 42 of clusters and a foot model 36-143 mm from them. Stood on the
    template, the foreign markers fill names within the tolerance, and taken for the whole
    set its 81 pieces went to the swap search, which gave 0 of 39 names right (5 silent
    wrong). The set's own markers alone are the whole set; with the others beside them
    the trial is labelled as a part of the set among other markers (a stature found)."""
    crop = np.load(FIXTURES / "pycgm" / "movement_trial_crop.npz")
    xyz, labels = crop["xyz_mm"].astype(float), list(crop["labels"])
    params = reconstructed_points(TrackingParams()).replace(label_window_fields=120)

    def stature(channels: list[int]) -> float:
        f, k = np.nonzero(np.isfinite(xyz[:, channels, 0]))
        at = xyz[f, np.asarray(channels)[k]]
        tracks = make_tracks(f, k, at, at, np.zeros(f.size, np.int8), np.arange(f.size))
        return partial_height(tracks, FULL, params)

    own = [i for i, name in enumerate(labels) if name in FULL.names]
    assert len(own) == len(FULL.names) and len(labels) - len(own) == 42
    assert np.isnan(stature(own))
    assert np.isfinite(stature(list(range(len(labels)))))


def test_among_another_sets_markers_rigid_segments_do_not_vouch_for_names_shifted_along_a_leg():
    """pyCGM's Movement_trial (fixtures/real/pycgm/) named as the first window matched it
    at 1.85 m: the thigh's name on the knee marker, the knee's on a shank cluster marker
    (*126), the right knee's on the tibia marker. The knee marker sits on the knee's axis,
    rigid with the shank's cluster (5.5 mm SD), so the thigh segment held the shifted
    names rigidly and vouched for them: 3 names wrong and silent over the trial. With the
    other set's markers beside them, a name rigid to an unnamed marker is doubted; the
    set's own markers alone keep every right name vouched."""
    crop = np.load(FIXTURES / "pycgm" / "movement_trial_crop.npz")
    xyz, labels = crop["xyz_mm"].astype(float), list(crop["labels"])

    def labelling(held: dict[str, str], channels: list[int]) -> Labelling:
        f, k = np.nonzero(np.isfinite(xyz[:, channels, 0]))
        at = xyz[f, np.asarray(channels)[k]]
        tracks = make_tracks(f, k, at, at, np.zeros(f.size, np.int8), np.arange(f.size))
        name_of = {channels.index(labels.index(m)): n for n, m in held.items()}
        named = tuple(name_of.get(t, f"M{t}") for t in range(len(channels)))
        unnamed = tuple(t for t in range(len(channels)) if t not in name_of)
        return Labelling(tracks, named, True, unnamed, (), 0.0)

    right = {n: n for n in FULL.names}
    own = [labels.index(n) for n in FULL.names]
    assert unvouched(labelling(right, own), FULL) == ()
    # The legs as the whole trial was named (main 9966019); the thighs' and the right
    # knee's names were silent, the others flagged or on markers outside the set.
    shift = {"LTHI": "LKNE", "LKNE": "*126", "LTIB": "*131", "LANK": "*128", "LTOE": "*133"}
    shift |= {"RTHI": "RKNE", "RKNE": "RTIB", "RTIB": "RANK", "RANK": "*147", "RTOE": "*149"}
    doubted = unvouched(labelling(right | shift, list(range(len(labels)))), FULL)
    assert {"LTHI", "RTHI", "RKNE"} <= set(doubted)
