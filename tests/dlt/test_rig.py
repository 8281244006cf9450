"""calibrate_rods: the whole rig from rod images (own KISS-like rig)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import DltParams, calibrate_rods
from kisscal.errors import KisscalError
from tests.dlt.conftest import kiss_rig, rod_image


def test_calibrate_rods_with_frames_and_a_hidden_marker():
    rig = kiss_rig(4)
    rng = np.random.default_rng(4)
    blobs = {}
    for cam in range(6):
        frames = [rod_image(rig, cam, rng, hide=3 if cam == 2 else None)[0] for _ in range(4)]
        blobs[f"cam{cam + 1}"] = frames
    cal = calibrate_rods(blobs, rig.rods, DltParams(mdlt=True))
    assert cal.matches["cam3"].missing == ("R1[3]",)
    assert len(cal.labels["cam3"]) == 23 and "R1[3]" not in cal.labels["cam3"]
    for k, cam in enumerate(blobs):
        r = cal.results[cam]
        # Averaging 4 frames halves the noise: rms about 0.062 / 2
        assert r.rms_px < 0.05
        assert np.linalg.norm(r.centre_mm - rig.centre_mm[k]) < 10
        assert abs(r.constraint) < 1e-9
    assert np.nanmean(cal.in_sample_mm) < 0.3
    assert cal.check is not None and cal.check.overall_mean_mm < 2


def test_a_camera_seeing_too_little_is_named():
    rig = kiss_rig(4)
    rng = np.random.default_rng(5)
    blobs = {f"cam{c + 1}": rod_image(rig, c, rng)[0] for c in range(6)}
    uv, truth = rod_image(rig, 1, rng, n_extra=0)
    blobs["cam2"] = uv[truth[:12]]  # only rods R1 and R2 in view: one vertical plane
    with pytest.raises(KisscalError, match=r"camera cam2: .*coplanar.*rods R3, R4"):
        calibrate_rods(blobs, rig.rods)
