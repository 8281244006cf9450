"""out/dlt/<camera>.json and dltdv.csv: written, read back, external files accepted."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kisscal.dlt import DltParams, calibrate_camera, project
from kisscal.dlt.model import dlt_to_matrix
from kisscal.dlt.nonlinear import lens_frame
from kisscal.errors import KisscalError
from kisscal.io.dltfiles import read_dlt_json, read_dltdv_csv, write_dlt_json, write_dltdv_csv
from tests.dlt.conftest import rod_xyz


def _result(rig, cam, params):
    xyz = rod_xyz(rig)
    uv = project(rig.L[cam], xyz) + np.random.default_rng(cam).normal(0, 0.05, (24, 2))
    return xyz, uv, calibrate_camera(xyz, uv, params)


def test_json_round_trip(rig, tmp_path):
    xyz, uv, result = _result(rig, 0, DltParams(mdlt=True))
    labels = [f"R{i // 6 + 1}.{i % 6 + 1}" for i in range(24)]
    path = write_dlt_json(
        tmp_path / "out/dlt/cam1.json", "cam1", result, xyz, uv, labels, kinds="rod"
    )
    back = read_dlt_json(path)
    assert back.camera == "cam1" and back.method == "mdlt" and back.lens is None
    np.testing.assert_array_equal(back.L, result.L)  # exact: repr of floats
    assert back.rms_px == result.rms_px
    doc = json.loads(path.read_text())
    assert "sqrt(mean(du^2 + dv^2))" in doc["rms_definition"]
    assert doc["points"][7]["label"] == "R2.2" and doc["points"][7]["kind"] == "rod"
    du = np.array([[p["du_px"], p["dv_px"]] for p in doc["points"]])
    assert np.sqrt(np.mean((du**2).sum(axis=1))) == pytest.approx(doc["rms_px"])
    np.testing.assert_allclose(doc["centre_mm"], result.centre_mm)
    assert abs(doc["constraint_violation"]) < 1e-9
    assert np.array(doc["K"]).shape == (3, 3)


def test_control_points_say_what_they_are(rig, tmp_path):
    """Every control point is written with its kind, one for all or one each; points
    without one, or of a kind kisscal does not know, are refused."""
    xyz, uv, result = _result(rig, 0, DltParams())
    labels = [f"W1@{i}" for i in range(24)]
    kinds = ["rod"] * 12 + ["wand"] * 12
    path = write_dlt_json(tmp_path / "c.json", "cam1", result, xyz, uv, labels, kinds=kinds)
    assert [p["kind"] for p in read_dlt_json(path).data["points"]] == kinds
    for wrong in (None, "wand?", kinds[:-1]):
        with pytest.raises(ValueError, match="kind"):
            write_dlt_json(tmp_path / "c.json", "cam1", result, xyz, uv, labels, kinds=wrong)


def test_external_json_with_only_camera_and_L(rig, tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"camera": "camA", "L": rig.L[1].tolist()}))
    back = read_dlt_json(path)
    assert back.method == "external" and np.isnan(back.rms_px)
    np.testing.assert_array_equal(back.L, rig.L[1])


@pytest.mark.parametrize(
    ("text", "message"),
    [("{", "not valid JSON"), ('{"camera": "c"}', '"L" list'), ('{"L": [1, 2]}', "11 finite")],
)
def test_bad_json_is_a_clear_error(tmp_path, text, message):
    path = tmp_path / "c.json"
    path.write_text(text)
    with pytest.raises(KisscalError, match=message):
        read_dlt_json(path)


def test_dltdv_round_trip(rig, tmp_path):
    Ls = {f"cam{i + 1}": rig.L[i] for i in range(6)}
    path = write_dltdv_csv(tmp_path / "dltdv.csv", Ls)
    lines = path.read_text().splitlines()
    assert len(lines) == 11 and all(len(line.split(",")) == 6 for line in lines)
    back = read_dltdv_csv(path, cameras=list(Ls))
    for cam, L in Ls.items():
        np.testing.assert_allclose(back[cam].L, L, rtol=1e-12, atol=1e-15)
    with pytest.raises(KisscalError, match="give the camera ids"):
        read_dltdv_csv(path)
    with pytest.raises(KisscalError, match="6 columns of coefficients for 2 cameras"):
        read_dltdv_csv(path, cameras=["a", "b"])


def test_dltdv_with_header_and_bad_rows(rig, tmp_path):
    path = tmp_path / "coefs.csv"
    pairs = zip(rig.L[0].tolist(), rig.L[1].tolist(), strict=True)
    rows = ["left,right"] + [f"{a!r},{b!r}" for a, b in pairs]
    path.write_text("\n".join(rows) + "\n")
    back = read_dltdv_csv(path)
    assert list(back) == ["left", "right"]
    # the file is in DLTdv8's pixels (first pixel 1): kisscal's are 1 px less
    uv = project(back["right"].L, rod_xyz(rig))
    np.testing.assert_allclose(uv + 1, project(rig.L[1], rod_xyz(rig)), atol=1e-9)
    path.write_text("\n".join(rows[:8]) + "\n")
    with pytest.raises(KisscalError, match="expected 11 rows"):
        read_dltdv_csv(path)


def test_control_points_csv(rig, tmp_path):
    from kisscal.io.dltfiles import read_control_points_csv

    xyz = rod_xyz(rig)
    uv = project(rig.L[0], xyz)
    path = tmp_path / "cam1.csv"
    lines = ["label,u_px,v_px,x_mm,y_mm,z_mm"]
    lines += [
        f"F{i},{u!r},{v!r},{x!r},{y!r},{z!r}"
        for i, (u, v, x, y, z) in enumerate(np.hstack([uv, xyz]).tolist())
    ]
    path.write_text("\n".join(lines) + "\n")
    uv2, xyz2, labels = read_control_points_csv(path)
    np.testing.assert_array_equal(uv2, uv)
    np.testing.assert_array_equal(xyz2, xyz)
    assert labels[3] == "F3"
    result = calibrate_camera(xyz2, uv2, DltParams())
    assert result.rms_px < 1e-6
    path.write_text("u_px,v_px,x_mm,y_mm,zz_mm\n1,2,3,4,5\n")
    with pytest.raises(KisscalError, match="missing z_mm; unknown zz_mm"):
        read_control_points_csv(path)


def test_pixel_unit_lens_terms_on_non_square_pixels_ask_for_a_new_calibration(rig, tmp_path):
    """Lens terms written in the older pixel-unit form mean the same lens only on square
    pixels: read there, refused with one line where the pixels are twice as tall."""
    old = "Kolahi et al. 2007 eq. 2 (L12..L16), applied to observed pixels"
    square = rig.L[1].copy()
    square[4:8] /= lens_frame(dlt_to_matrix(square))[1][1, 1]  # the KISS pixel aspect undone
    tall = square.copy()
    tall[4:8] *= 2.0  # v = 2 v: pixels twice as tall as wide
    lens = [-1e-8, 0.0, 0.0, 0.0, 0.0]
    for name, L, model, fails in [
        ("square", square, old, False),
        ("tall_old", tall, old, True),
        ("tall_new", tall, None, False),
    ]:
        doc = {"camera": name, "L": L.tolist(), "lens": lens}
        if model is not None:
            doc["lens_model"] = model
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(doc))
        if fails:
            with pytest.raises(KisscalError, match=r"pixel-unit form .* calibrate"):
                read_dlt_json(path)
        else:
            np.testing.assert_array_equal(read_dlt_json(path).lens, lens)
