"""n-camera triangulation: exact on exact data, reweighting lowers reprojection error."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.dlt.triangulate import triangulate, triangulate_observations
from kisscal.errors import KisscalError

from .rig import make_rig, random_markers


def _dense(dlts: np.ndarray, xyz: np.ndarray, noise_px: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    uv = np.stack([project(L, xyz) for L in dlts], axis=1)
    return uv + rng.normal(0, noise_px, uv.shape)


def test_exact_data_is_reconstructed_exactly_from_two_to_six_cameras() -> None:
    dlts = make_rig(0)
    xyz = random_markers(np.random.default_rng(0), 1, 200)[0]
    uv = _dense(dlts, xyz, 0.0, 0)
    for n in range(2, 7):
        sub = uv.copy()
        sub[:, n:] = np.nan
        t = triangulate(dlts, sub)
        assert np.abs(t.xyz_mm - xyz).max() < 1e-6
        assert np.all(t.n_cameras == n)
        assert t.rms_px.max() < 1e-6


def test_reweighted_step_lowers_reprojection_rms_and_3d_error() -> None:
    dlts = make_rig(1)
    xyz = random_markers(np.random.default_rng(1), 1, 2000)[0]
    uv = _dense(dlts, xyz, 0.5, 1)
    plain = triangulate(dlts, uv, reweight_iterations=0)
    weighted = triangulate(dlts, uv, reweight_iterations=2)
    assert np.mean(weighted.rms_px) < np.mean(plain.rms_px)
    assert np.all(weighted.rms_px <= plain.rms_px + 1e-9)
    err_plain = np.linalg.norm(plain.xyz_mm - xyz, axis=1)
    err_weighted = np.linalg.norm(weighted.xyz_mm - xyz, axis=1)
    assert np.sqrt(np.mean(err_weighted**2)) <= np.sqrt(np.mean(err_plain**2))


def test_rms_is_rms_euclidean_distance() -> None:
    dlts = make_rig(2)
    xyz = random_markers(np.random.default_rng(2), 1, 30)[0]
    uv = _dense(dlts, xyz, 0.3, 2)
    t = triangulate(dlts, uv)
    reproj = np.stack([project(L, t.xyz_mm) for L in dlts], axis=1)
    want = np.sqrt(np.mean(np.sum((reproj - uv) ** 2, axis=2), axis=1))
    assert np.allclose(t.rms_px, want)


def test_one_camera_gives_nan_and_bad_shapes_raise() -> None:
    dlts = make_rig(3)
    t = triangulate_observations(dlts, [0, 1, 1], [0, 0, 1], [[1, 2], [3, 4], [5, 6]], 2)
    assert np.all(np.isnan(t.xyz_mm[0])) and np.all(np.isfinite(t.xyz_mm[1]))
    with pytest.raises(KisscalError):
        triangulate(dlts[:, :10], np.zeros((1, 6, 2)))
    with pytest.raises(KisscalError):
        triangulate(dlts, np.zeros((1, 5, 2)))
