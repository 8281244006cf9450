"""The trials bundle's leave-one-rod-out refits in worker processes
(:func:`kisscal.session.routes.trial_bundle.left_out_by_rod`)."""

from __future__ import annotations

import numpy as np

from kisscal.bundle.params import BundleParams
from kisscal.bundle.points import POINT, calibrate_on_points
from kisscal.bundle.quality import leave_control_out
from kisscal.camera import Camera
from kisscal.dlt import calibrate_camera
from kisscal.session.routes.trial_bundle import left_out_by_rod
from tests.bundle.conftest import scene
from tests.bundle.test_points import _leftover_lens, _noisy_rods


def test_rods_left_out_in_workers_give_the_arrays_of_one_process() -> None:
    """Four rods and a trial's markers adjusted together: each rod's refit done in its
    own worker gives every left-out marker's error bit for bit as the refits done one
    after the other in this process, rod by rod in the same order."""
    s = _leftover_lens(scene(2, 60))
    table = s.blobs(ideal=False, noise_px=0.05, leds=False)
    control, rows = _noisy_rods(s, 0.01)
    starts = [
        Camera.from_dlt(calibrate_camera(control.xyz_mm[r], control.uv_px[r]).L) for r in rows
    ]
    params = BundleParams().on_grid()
    cal = calibrate_on_points(table, starts, control, s.sizes, params)
    one = leave_control_out(cal, POINT, cal.control.group, params)
    two = left_out_by_rod(cal, params, workers=2)
    assert len(np.unique(one[1])) == 4 and np.isfinite(one[2]).all()
    for a, b in zip(one, two, strict=True):
        np.testing.assert_array_equal(a, b)
