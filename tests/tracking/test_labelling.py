import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.tracking import TrackingParams, build_trajectories, label_tracks
from tests.tracking._data import NAMES, gait_truth, observe, rotation, template
from tests.tracking._eval import score


@pytest.mark.parametrize(
    ("seed", "heading_deg", "template_rotation"),
    [
        (0, 0.0, np.eye(3)),
        (1, 180.0, rotation(2, 123.0)),  # walks the other way; template turned
        (2, 63.0, rotation(0, 90.0)),  # template in a Y-up frame
        (3, -110.0, rotation(1, 35.0) @ rotation(2, -70.0)),
    ],
)
def test_labels_do_not_depend_on_where_subject_stands_or_faces(
    seed, heading_deg, template_rotation
):
    truth = gait_truth(300, seed)
    turn = rotation(2, heading_deg)
    truth = truth @ turn.T + [400.0, -900.0, 0.0]
    field, xyz, _, visible = observe(truth, seed, volume_x=None, ghosts_per_field=1.0)
    tmpl = template() @ template_rotation.T + [2000.0, 50.0, -300.0]
    result = build_trajectories(field, xyz, TrackingParams(), NAMES, tmpl)
    s = score(result, truth, visible, NAMES)
    assert result.labelling.fits_marker_set
    assert s.one_per_marker
    assert s.labels_correct == len(NAMES)


def test_stick_or_ball_gets_generic_names():
    f = np.arange(100.0)[:, None]
    a = np.hstack([10 * f, 0 * f, 1000 + 0 * f])
    b = a + np.array([0, 502.5, 0])
    field = np.r_[np.arange(100), np.arange(100)]
    xyz = np.r_[a, b]
    result = build_trajectories(field, xyz, TrackingParams(), NAMES, template())
    assert not result.labelling.fits_marker_set
    assert result.labels == ("M1", "M2")


def test_track_outside_the_marker_set_is_reported_not_dropped():
    truth = gait_truth(300, 4)
    extra = truth[0] + [0.0, 0.0, 450.0]  # a marker high on the back, not in the set
    field, xyz, _, visible = observe(np.concatenate([truth, extra[None]]), 4, volume_x=None)
    result = build_trajectories(field, xyz, TrackingParams(), NAMES, template())
    assert result.tracks.n_tracks == 16
    assert len(result.labelling.unlabelled) == 1
    t = result.labelling.unlabelled[0]
    assert result.labels[t].startswith("M")
    s = score(result, np.concatenate([truth, extra[None]]), visible, (*NAMES, "EXTRA"))
    assert s.labels_correct == 15


def test_template_shape_is_checked():
    truth = gait_truth(100, 0)
    field, xyz, _, _ = observe(truth, 0, volume_x=None)
    tracks = build_trajectories(field, xyz).tracks
    with pytest.raises(KisscalError):
        label_tracks(tracks, NAMES, TrackingParams(), template()[:5])
