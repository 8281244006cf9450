"""Body fill about a marker and a joint centre (kisscal.tracking.fill_centre), where one
camera's ray is tangent to every partner's sphere, against truth."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.tracking import TrackingParams, is_filled
from kisscal.tracking.gaps import fill_gaps_logged
from tests.tracking.test_bodyfill import _tracks_of
from tests.tracking.test_joint_centres import one_camera, walk

PARAMS = TrackingParams()
NAMES = ("RTHI", "RKNE", "RTIB", "SACR", "RASI", "LASI")
HIDDEN = slice(205, 250)


@pytest.mark.parametrize("seed", [2, 5])
def test_a_thigh_marker_seen_along_its_plane_s_normal_is_filled_about_knee_and_hip(seed):
    # lowcost 413 RTHI, 401 and 420 LTHI: one camera in front of the walker sees the
    # thigh marker, its ray square to the thigh's plane (marker, knee, hip): it meets the
    # knee's and the hip's spheres at a glancing angle (cosines under 0.13 here), and
    # main left 38 of the 45 fields open. The knee and the hip centre the pelvis carries
    # hold the marker's place about the thigh's axis.
    xyz, hip = walk(seed=seed)
    xyz = xyz[[3, 4, 5, 0, 1, 2]]  # thigh, knee, tibia, then the pelvis
    m = (HIDDEN.start + HIDDEN.stop) // 2
    normal = np.cross(xyz[0, m] - hip[m], xyz[1, m] - hip[m])
    spare = one_camera(xyz, 0, seed, 3000.0 * normal / np.linalg.norm(normal))
    out, fills = fill_gaps_logged(_tracks_of(xyz, {0: HIDDEN}), PARAMS, spare, labels=NAMES)
    rows = np.flatnonzero(is_filled(out.status) & (out.track == 0))
    f = out.field[rows]
    assert sorted(f.tolist()) == list(range(HIDDEN.start, HIDDEN.stop))
    err = np.linalg.norm(out.xyz_mm[rows] - xyz[0, f], axis=1)
    assert err.max() < 2.0
    for g in (g for g in fills if g.track == 0):  # each fill expected its error
        e = err[(f >= g.first_field) & (f < g.first_field + g.n_fields)]
        assert np.sqrt(np.mean(e**2)) <= 2.0 * g.expected_error_mm
