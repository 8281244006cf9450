"""A piece that two pelvis names' partners allow alike takes the name whose trajectory
it continues (labelling.spread.by_continuity), on pieces cut from the walking model."""

import numpy as np
import pytest

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling import label_tracks
from kisscal.tracking.tracks import make_tracks
from tests.tracking._data import NAMES, SEGMENTS, gait_truth, template

#: The sacrum moved back so that it lies as far from each ASIS as they lie apart: one
#: ASIS seen tells neither name from the other (kiss 3 seed 366's pelvis).
BACK = np.array([-46.3, 0.0, 0.0])
FEET = ("RANK", "RHEE", "RTOE", "LANK", "LHEE", "LTOE")


@pytest.mark.parametrize("cut", ["SACR", "RASI"])
def test_a_piece_after_its_name_s_end_takes_the_name_it_continues(cut):
    truth = gait_truth(200, 2)
    truth[0] += BACK
    tmpl = template()
    tmpl[0] += BACK
    m = NAMES.index(cut)
    other = NAMES.index("RASI" if cut == "SACR" else "SACR")
    # ``cut`` unseen over 100-115, then a piece of its own; ``other`` gone after 105; the
    # other ASIS and the feet seen throughout (the body fit, from the feet, is ~200 mm off)
    pieces = [(m, 0, 100), (m, 115, 200), (other, 0, 105), (2, 0, 200)]
    pieces += [(NAMES.index(n), 0, 200) for n in FEET]
    f = np.concatenate([np.arange(lo, hi) for _, lo, hi in pieces])
    t = np.concatenate([np.full(hi - lo, k) for k, (_, lo, hi) in enumerate(pieces)])
    xyz = np.concatenate([truth[j, lo:hi] for j, lo, hi in pieces])
    xyz += np.random.default_rng(0).normal(0, 0.5, xyz.shape)
    tracks = make_tracks(f, t, xyz, np.full(xyz.shape, np.nan), np.zeros(f.size), np.arange(f.size))
    segments = (*SEGMENTS, ("RASI", "SACR"), ("LASI", "SACR"))
    got = label_tracks(tracks, NAMES, TrackingParams(), tmpl, segments)
    assert not got.unlabelled
    own = got.tracks.track == got.labels.index(cut)
    assert np.isin(np.arange(115, 200), got.tracks.field[own]).all()
    err = np.linalg.norm(got.tracks.xyz_mm[own] - truth[m, got.tracks.field[own]], axis=1)
    assert err.max() < 3.0
