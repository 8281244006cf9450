"""calibrate_rods: the whole rig from rod images (own KISS-like rig)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import DltParams, calibrate_rods
from kisscal.errors import KisscalError
from tests.dlt.conftest import kiss_rig, rod_image


def _calibration():
    rig = kiss_rig(4)
    rng = np.random.default_rng(4)
    blobs = {}
    for cam in range(6):
        frames = [rod_image(rig, cam, rng, hide=3 if cam == 2 else None)[0] for _ in range(4)]
        blobs[f"cam{cam + 1}"] = frames
    return rig, blobs, calibrate_rods(blobs, rig.rods, DltParams(mdlt=True))


def test_calibrate_rods_with_frames_and_a_hidden_marker():
    rig, blobs, cal = _calibration()
    assert cal.matches["cam3"].missing == ("R1.4",)
    assert len(cal.labels["cam3"]) == 23 and "R1.4" not in cal.labels["cam3"]
    for k, cam in enumerate(blobs):
        r = cal.results[cam]
        # Averaging 4 frames halves the noise: rms about 0.062 / 2
        assert r.rms_px < 0.05
        assert np.linalg.norm(r.centre_mm - rig.centre_mm[k]) < 10
        assert abs(r.constraint) < 1e-9
    assert np.nanmean(cal.in_sample_mm) < 0.3
    assert cal.check is not None and cal.check.overall_mean_mm < 2
    summary = cal.summary()
    assert summary["cameras"]["cam3"]["missing"] == ["R1.4"]
    assert summary["leave_one_rod_out"]["mean_mm"] == cal.check.overall_mean_mm


def test_write_dlt_outputs(tmp_path):
    import json

    from kisscal.io.dltfiles import read_dlt_json, read_dltdv_csv, write_dlt_outputs
    from kisscal.io.store import SessionStore

    cal = _calibration()[2]
    store = SessionStore(tmp_path)
    paths = write_dlt_outputs(cal, store.dlt_path, store.dltdv_path)
    assert sorted(p.name for p in paths) == [*(f"cam{i}.json" for i in range(1, 7)), "dltdv.csv"]
    doc = json.loads((tmp_path / "out/dlt/cam3.json").read_text())
    assert doc["rods"]["missing"] == ["R1.4"] and len(doc["points"]) == 23
    assert {p["kind"] for p in doc["points"]} == {"rod"}
    assert doc["rig"]["leave_one_rod_out"]["mean_mm"] > 0
    back = read_dltdv_csv(tmp_path / "out/dlt/dltdv.csv", [f"cam{i}" for i in range(1, 7)])
    np.testing.assert_array_equal(back["cam3"].L, read_dlt_json(paths[2]).L)


def test_a_camera_seeing_too_little_is_named():
    rig = kiss_rig(4)
    rng = np.random.default_rng(5)
    blobs = {f"cam{c + 1}": rod_image(rig, c, rng)[0] for c in range(6)}
    uv, truth = rod_image(rig, 1, rng, n_extra=0)
    blobs["cam2"] = uv[truth[:12]]  # only rods R1 and R2 in view: one vertical plane
    with pytest.raises(KisscalError, match=r"camera cam2: .*coplanar.*rods R3, R4"):
        calibrate_rods(blobs, rig.rods)


def test_lens_terms_through_the_whole_rig():
    # Without linearisation: Kolahi's lens terms absorb a mild radial distortion.
    from kisscal.dlt.model import dlt_to_matrix
    from kisscal.dlt.nonlinear import lens_frame, lens_offsets

    rig = kiss_rig(6)
    rng = np.random.default_rng(6)
    # r in square pixels: the rods bend as much as -6e-7 bent them in raw pixels
    lens = np.array([-1.6e-7, 0, 0, 0, 0])
    blobs = {}
    for cam in range(6):
        uv, _ = rod_image(rig, cam, rng, n_extra=2)
        ideal = uv.copy()
        for _ in range(30):  # observed = ideal - offsets(observed)
            uv = ideal - lens_offsets(uv, lens_frame(dlt_to_matrix(rig.L[cam])), lens)
        blobs[f"cam{cam + 1}"] = uv
    plain = calibrate_rods(blobs, rig.rods, DltParams(refine=True))
    with_lens = calibrate_rods(blobs, rig.rods, DltParams(lens=True))
    assert with_lens.check is not None
    for cam in blobs:
        assert with_lens.results[cam].rms_px < 0.5 * plain.results[cam].rms_px
    assert np.nanmean(with_lens.in_sample_mm) < np.nanmean(plain.in_sample_mm)


def test_one_camera_alone(recwarn):
    # kisscal calibrate --camera C: no 3D check possible, no NaN warnings, no NaN in summary
    rig = kiss_rig(4)
    blobs, _ = rod_image(rig, 0, np.random.default_rng(0))
    cal = calibrate_rods({"cam1": blobs}, rig.rods)
    assert cal.check is None and np.isnan(cal.in_sample_mm).all()
    assert cal.results["cam1"].rms_px < 0.08
    summary = cal.summary()
    assert "rods_in_sample_mean_mm" not in summary and "leave_one_rod_out" not in summary
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_markers_hidden_in_some_frames_only_are_not_missing():
    rig = kiss_rig(4)
    rng = np.random.default_rng(3)
    frames = [rod_image(rig, 0, rng, hide=h)[0] for h in (5, 5, None)]
    blobs = {"cam1": frames, "cam2": rod_image(rig, 1, rng, hide=9)[0]}
    cal = calibrate_rods(blobs, rig.rods)
    assert cal.matches["cam1"].missing == ()
    assert cal.matches["cam2"].missing == ("R2.4",)
    assert len(cal.labels["cam1"]) == 24
