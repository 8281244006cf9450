"""The last contest for each foot's names (:mod:`kisscal.tracking.labelling.feet`)."""

import numpy as np

from kisscal.markersets import marker_set
from kisscal.tracking.labelling.feet import foot_contest
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
