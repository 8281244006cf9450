"""The out/linearisation/<camera>.json file: round trip and use by a tool without kisscal."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.grid import apply_linearisation, linearise_dots
from kisscal.io.linearisation import read_linearisation, write_linearisation
from tests.grid.grid_synth import make_grid_view


@pytest.fixture(scope="module")
def fit():
    view = make_grid_view(seed=21)
    keep = np.ones(300, dtype=bool)
    keep[[17, 140]] = False
    return linearise_dots(view.dots_uv[keep], size_px=(752, 291))


def test_round_trip_keeps_coefficients_and_quality(tmp_path, fit):
    lin = fit.linearisation
    path = write_linearisation(
        tmp_path / "out" / "linearisation" / "cam1.json",
        lin,
        "cam1",
        fit.index.missing_rc,
        fit.index.missing_uv,
    )
    camera, back = read_linearisation(path)
    assert camera == "cam1"
    np.testing.assert_array_equal(back.x, lin.x)
    np.testing.assert_array_equal(back.y, lin.y)
    assert back.center_px == lin.center_px and back.scale_px == lin.scale_px
    assert back.quality == lin.quality
    doc = json.loads(path.read_text())
    assert doc["model"] == "poly4" and doc["grid"] == {"rows": 15, "cols": 20}
    assert doc["dots_used"] == 298 and len(doc["missing"]) == 2
    assert doc["rms_px"] == pytest.approx(lin.quality.residual_rms_after_px)


def test_a_tool_can_apply_it_from_the_file_alone(tmp_path, fit):
    """Evaluate the DESIGN.md formula from the JSON with plain Python, no kisscal."""
    path = write_linearisation(tmp_path / "cam1.json", fit.linearisation, "cam1")
    doc = json.loads(path.read_text())
    (cu, cv), s = doc["center_px"], doc["scale_px"]
    pts = np.random.default_rng(1).uniform([0, 0], [751, 290], size=(50, 2))
    powers = {"1": (0, 0), "u": (1, 0), "v": (0, 1)}
    for name in doc["terms"]:
        if name not in powers:
            a = name.count("u") if "u^" not in name else int(name[name.index("u^") + 2])
            b = name.count("v") if "v^" not in name else int(name[name.index("v^") + 2])
            powers[name] = (a, b)
    for (u, v), expected in zip(pts, apply_linearisation(fit.linearisation, pts), strict=True):
        un, vn = (u - cu) / s, (v - cv) / s
        t = [un ** powers[n][0] * vn ** powers[n][1] for n in doc["terms"]]
        assert sum(c * x for c, x in zip(doc["x"], t, strict=True)) == pytest.approx(
            expected[0], abs=1e-9
        )
        assert sum(c * x for c, x in zip(doc["y"], t, strict=True)) == pytest.approx(
            expected[1], abs=1e-9
        )


def test_minimal_file_is_enough(tmp_path):
    x = [0.0] * 15
    y = [0.0] * 15
    x[0], x[1], y[0], y[2] = 10.0, 2.0, 20.0, 2.0
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"camera": "c", "center_px": [0, 0], "scale_px": 2, "x": x, "y": y}))
    _, lin = read_linearisation(path)
    assert lin.quality is None
    np.testing.assert_allclose(apply_linearisation(lin, [[1.0, 1.0]]), [[11.0, 21.0]])


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "not valid JSON"),
        ('{"center_px": [0, 0], "scale_px": 1, "x": [0]}', "missing key 'y'"),
        ('{"center_px": [0, 0], "scale_px": 1, "x": [0], "y": [0]}', "15 x and 15 y"),
        (
            '{"model": "radial", "center_px": [0, 0], "scale_px": 1, "x": [], "y": []}',
            "unknown linearisation model",
        ),
    ],
)
def test_bad_files_name_the_problem(tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(KisscalError, match=message):
        read_linearisation(path)
    with pytest.raises(KisscalError, match="not found"):
        read_linearisation(tmp_path / "nope.json")
