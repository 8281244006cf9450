"""The vertical found from the data (kisscal.tracking.labelling.vertical)."""

import numpy as np
import pytest

from kisscal.markersets import marker_set
from kisscal.synth.motion import walking_trial
from kisscal.tracking import TrackingParams, blend_tracks, track_points
from kisscal.tracking.labelling import label_with_set
from kisscal.tracking.labelling.vertical import (
    axis_rotation,
    floor_sign,
    turned,
    upright_rotation,
)

KISS = marker_set("kiss")
UP = np.array([0.0, 0.0, 1.0])


def _walk():
    m = walking_trial(2, 150, 50.0, path_mm=3500, model="grounded", height_m=1.6, heading_deg=230)
    f, k = np.nonzero(np.isfinite(m.xyz_mm[..., 0]))
    pieces = blend_tracks(track_points(f, m.xyz_mm[f, k], TrackingParams()), TrackingParams())
    return m, pieces


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("sign", [1, -1])
def test_axis_rotation_is_proper_and_takes_the_axis_up(axis, sign):
    r = axis_rotation(axis, sign)
    e = np.zeros(3)
    e[axis] = sign
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_array_equal(r @ e, UP)
    np.testing.assert_array_equal(r @ r.T, np.eye(3))


@pytest.mark.parametrize("axis,sign", [(2, 1), (1, 1), (1, -1), (0, 1), (0, -1)])
def test_the_vertical_of_a_turned_lab_is_found(axis, sign):
    """A walk whose lab has ``axis`` times ``sign`` up (Y up, X up, negative axes): the
    rotation found puts the walker's true up (that lab axis) back at +Z."""
    _, pieces = _walk()
    lab = axis_rotation(axis, sign).T  # the lab's axis (x sign) holds the walker's up
    found = upright_rotation(turned(pieces, lab), KISS, TrackingParams())
    np.testing.assert_allclose(found @ lab @ UP, UP, atol=1e-12)


def test_a_y_up_walk_gets_the_z_up_walks_names():
    m, pieces = _walk()
    lab = axis_rotation(1, 1).T  # Y up, as NexGen and Phoenix write
    found = label_with_set(turned(pieces, lab), KISS, TrackingParams(), 50.0)
    t = found.tracks
    right = [
        np.allclose(t.xyz_mm[t.track == i][0] @ lab, m.xyz_mm[t.field[t.track == i][0], j])
        for i, name in enumerate(found.labels)
        for j in [m.names.index(name)]
    ]
    assert len(right) == 15 and all(right) and found.certain


def test_floor_sign_finds_the_steady_end():
    rng = np.random.default_rng(1)
    fields = 200
    feet = rng.uniform(0, 2, (4, fields))  # one foot always on the floor: lowest steady
    head = 1600 + 30 * np.sin(np.linspace(0, 12, fields)) + rng.normal(0, 5, (3, fields))
    height = np.vstack([feet, head])
    assert floor_sign(height) == 1
    assert floor_sign(-height) == -1
    assert floor_sign(np.full((3, fields), 5.0)) == 0  # a still subject tells nothing


def test_a_still_upper_body_is_not_stood_on_its_head():
    # shd01 (BTK): trunk, head, arms and pelvis, no leg marker, barely moving. With its
    # lowest piece (a wrist) put on the floor, it fitted the standing template better
    # upside down; on the lab's own floor it stands.
    full = marker_set("plug-in-gait-full")
    keep = [n for n in full.names if n[1:] not in ("THI", "KNE", "TIB", "ANK", "HEE", "TOE")]
    body = full.template_mm[[full.index(n) for n in keep]] @ axis_rotation(2, 1)
    rng = np.random.default_rng(5)
    sway = 20.0 * np.sin(np.linspace(0.0, np.pi, 100))[:, None, None] * [1.0, 0.5, 0.0]
    xyz = body[None] + sway + [500.0, 300.0, 0.0] + rng.normal(0.0, 0.5, (100, len(keep), 3))
    f, k = np.nonzero(np.isfinite(xyz[..., 0]))
    pieces = blend_tracks(track_points(f, xyz[f, k], TrackingParams()), TrackingParams())
    np.testing.assert_array_equal(upright_rotation(pieces, full, TrackingParams()), np.eye(3))
