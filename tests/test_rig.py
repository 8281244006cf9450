"""The Rig: one object for cameras, linearisation, projection and triangulation."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.camera import Camera
from kisscal.dlt.model import dlt_from_krt, project
from kisscal.errors import KisscalError
from kisscal.grid.poly import Linearisation, apply_linearisation
from kisscal.rig import Rig


def _camera(cam_id: str, centre: tuple[float, float, float], lens: bool = False) -> Camera:
    K = np.array([[900.0, 0, 640], [0, 900, 512], [0, 0, 1]])
    c = np.asarray(centre)
    z = -c / np.linalg.norm(c)  # look at the origin
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    L = dlt_from_krt(K, R, -R @ c)
    x_coef = np.zeros(15)
    y_coef = np.zeros(15)
    x_coef[[0, 1, 6]] = 640.0, 640.0, 4.0  # u' = cu + s un + 4 un^3 (barrel-like)
    y_coef[[0, 2, 9]] = 512.0, 640.0, -3.0
    lin = Linearisation((640.0, 512.0), 640.0, x_coef, y_coef)
    terms = np.array([1e-8, 0.0, 0.0, 1e-6, -1e-6]) if lens else None
    return Camera.from_dlt(L, cam_id, lin, terms, (1280, 1024))


@pytest.fixture
def rig() -> Rig:
    return Rig(
        (
            _camera("a", (3000.0, -2500.0, 1500.0)),
            _camera("b", (-3000.0, -2500.0, 1200.0), lens=True),
            _camera("c", (0.0, 3500.0, 1800.0)),
        )
    )


def test_distort_inverts_linearise(rig: Rig) -> None:
    rng = np.random.default_rng(1)
    raw = rng.uniform([0, 0], [1279, 1023], (200, 2))
    for cam in rig:
        assert np.abs(cam.distort_px(cam.undistort_px(raw)) - raw).max() < 1e-7


def test_projection_and_triangulation_round_trip(rig: Rig) -> None:
    rng = np.random.default_rng(2)
    xyz = rng.uniform([-800, -600, 0], [800, 600, 1800], (50, 3))
    raw = np.stack([cam.project(xyz) for cam in rig])  # where the images show them
    blobs = {cam.id: [raw[i][:25], raw[i][25:]] for i, cam in enumerate(rig)}  # two fields
    obs = rig.observations(blobs)
    assert len(obs) == 150
    assert np.all(np.diff(obs.field * 10 + obs.camera) >= 0)  # sorted by field, camera
    point = np.tile(np.arange(25), 3)
    first = obs.field == 0
    order = np.lexsort((point, obs.camera[first]))  # rows of field 0: camera-major
    tri = rig.triangulate(obs.camera[first][order], obs.uv_px[first][order], point)
    assert np.abs(tri.xyz_mm - xyz[:25]).max() < 1e-6
    assert np.nanmax(tri.rms_px) < 1e-6


def test_project_matches_the_dlt_and_the_linearised_raw_points(rig: Rig) -> None:
    xyz = np.array([[100.0, -50.0, 900.0], [-300.0, 200.0, 100.0]])
    uv = rig.project(xyz)
    for i, cam in enumerate(rig):
        assert np.allclose(uv[i], project(cam.dlt, xyz))
        assert np.allclose(cam.undistort_px(cam.project(xyz)), uv[i], atol=1e-8)
    rows = rig.project_rows([2, 0], xyz)
    assert np.allclose(rows, [uv[2, 0], uv[0, 1]])


def test_without_linearisation_the_rig_is_the_plain_dlt() -> None:
    cam = _camera("a", (3000.0, -2500.0, 1500.0))
    plain = Camera.from_dlt(cam.dlt, "a")
    xy = np.array([[10.0, 20.0], [600.0, 700.0]])
    assert np.array_equal(plain.undistort_px(xy), xy)
    assert np.allclose(apply_linearisation(cam.linearisation, xy), cam.undistort_px(xy))


def test_index_and_errors(rig: Rig) -> None:
    sub = Rig((rig.camera("c"), rig.camera("a")))
    assert sub.ids == ("c", "a") and sub.index("a") == 1
    assert np.array_equal(sub.dlts[0], rig.camera("c").dlt)
    with pytest.raises(KisscalError, match="no camera 'z'"):
        rig.index("z")
    with pytest.raises(KisscalError, match="distinct"):
        Rig((rig.cameras[0], rig.cameras[0]))
    with pytest.raises(KisscalError, match="11 finite"):
        Camera.from_dlt(np.zeros(10), "x")
