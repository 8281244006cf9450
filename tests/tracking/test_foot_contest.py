"""The last contest for each foot's names (:mod:`kisscal.tracking.labelling.feet`)."""

import numpy as np

from kisscal.markersets import marker_set
from kisscal.tracking.labelling.feet import _contest, foot_contest
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.tracks import make_tracks

SHANK_FOOT = ("RKNE", "RTIB", "RANK", "RHEE", "RTOE")


def _walk(names, labels, unlabelled, missing):
    """Right shank and foot of the set's template carried 20 mm a field with a swinging
    foot (rotating about the ankle), noise 1 mm; one trajectory per name, labelled
    ``labels``."""
    mset = marker_set("plug-in-gait-full")
    rng = np.random.default_rng(0)
    base = np.array([mset.template_mm[mset.index(n)] for n in names])
    ankle = base[2]
    fields = np.arange(60)
    field, track, xyz = [], [], []
    for f in fields:
        a = 0.3 * np.sin(f / 6)
        rot = np.array([[np.cos(a), 0, -np.sin(a)], [0, 1, 0], [np.sin(a), 0, np.cos(a)]])
        pos = base.copy()
        pos[3:] = ankle + (base[3:] - ankle) @ rot.T  # the foot turns at the ankle
        pos += [20.0 * f, 0.0, 0.0]
        field += [f] * len(names)
        track += list(range(len(names)))
        xyz.append(pos + rng.normal(0.0, 1.0, pos.shape))
    n = len(field)
    tracks = make_tracks(
        np.array(field), np.array(track), np.concatenate(xyz),
        np.full((n, 3), np.nan), np.zeros(n), np.arange(n),
    )  # fmt: skip
    return mset, Labelling(
        tracks, tuple(labels), True, unlabelled, missing, 1.0, height_mm=mset.height_mm
    )


def test_a_foot_whose_names_the_match_rotated_gets_them_back():
    """As in a real Vicon walk: the ankle's trajectory named heel, the toe's ankle, the
    heel's unnamed. The distances to the knee and tibia markers and within the foot fit
    the template only with the names back in place; right names stay."""
    mset, wrong = _walk(SHANK_FOOT, ("RKNE", "RTIB", "RHEE", "RANK", "M1"), (4,), ("RTOE",))
    fixed = foot_contest(wrong, mset)
    assert fixed.labels == SHANK_FOOT
    assert fixed.unlabelled == () and "RTOE" not in fixed.missing
    mset, right = _walk(SHANK_FOOT, SHANK_FOOT, (), ())
    assert foot_contest(right, mset).labels == SHANK_FOOT


def test_a_piece_never_seen_with_the_rest_of_the_foot_takes_no_name():
    """Held heel, toe and ankle whose heel-toe distance is 30 % longer than the
    template's, and another piece on the heel never seen with the toe: scored without that
    distance it fits perfectly, and would take the heel's name; an assignment counts only
    when all its trajectories are seen together (the tennis serve: later pieces of the
    heel and toe took their names from the whole-trial trajectories)."""
    mset = marker_set("plug-in-gait-full")
    names = ("RKNE", "RTIB", "RHEE", "RTOE", "RANK")
    pos = np.array([mset.template_mm[mset.index(n)] for n in names])
    target = np.linalg.norm(pos[:, None] - pos[None, :], axis=2)
    d = np.full((6, 6), np.nan)
    d[:5, :5] = target
    d[2, 3] = d[3, 2] = 1.3 * target[2, 3]
    d[5, :5], d[:5, 5] = target[2], target[2]  # the second heel piece
    d[5, 3] = d[3, 5] = np.nan  # never seen with the toe
    d[5, 2] = d[2, 5] = 0.0
    d[5, 5] = 0.0
    cands, held = np.array([10, 11, 12, 13]), np.array([10, 11, 12])
    assert _contest(d, np.array([0, 1]), cands, held, target) is None
    d[5, 3] = d[3, 5] = target[2, 3]  # seen together and fitting: it takes the name
    assert list(_contest(d, np.array([0, 1]), cands, held, target)) == [13, 11, 12]
