"""A small KISS-like rig for the recon tests: 6 cameras, three per side of a walkway."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import dlt_from_krt, project

SIZE_PX = (752, 291)


def look_at(centre: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation of a camera at ``centre`` looking at ``target``, image y pointing down."""
    z = target - centre
    z = z / np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])


def make_rig(seed: int = 0, n_cameras: int = 6) -> NDArray[np.float64]:
    """DLT parameters (n_cameras, 11) of cameras around a 2.4 x 1.4 x 2 m volume."""
    rng = np.random.default_rng(seed)
    dlts = []
    for k in range(n_cameras):
        side = 1.0 if k % 2 == 0 else -1.0
        x = (-2200.0, 0.0, 2200.0)[(k // 2) % 3]
        centre = np.array([x, side * 3800.0, 1600.0]) + rng.normal(0, 100, 3)
        target = np.array([0.0, 0.0, 900.0]) + rng.normal(0, 50, 3)
        R = look_at(centre, target)
        f = 700.0 + rng.normal(0, 20)
        K = np.array([[f, 0.0, 376.0], [0.0, f * 0.5 * 291 / 288, 145.0], [0.0, 0.0, 1.0]])
        dlts.append(dlt_from_krt(K, R, -R @ centre))
    return np.array(dlts)


def random_markers(rng: np.random.Generator, n_fields: int, n_markers: int) -> NDArray:
    """Marker positions (n_fields, n_markers, 3) inside the control volume, mm."""
    lo = np.array([-1200.0, -700.0, 0.0])
    hi = np.array([1200.0, 700.0, 2000.0])
    return lo + (hi - lo) * rng.random((n_fields, n_markers, 3))


def make_table(
    rng: np.random.Generator,
    dlts: NDArray[np.float64],
    xyz: NDArray[np.float64],
    noise_px: float = 0.05,
    p_visible: float = 0.85,
    n_noise: int = 0,
    n_leds: int = 0,
) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray]:
    """Long-format 2D table of projected markers (+ ghosts) of every camera and field.

    Returns field, camera, uv, truth marker index (-1 for ghosts), visible (F, M, C).
    """
    n_fields, n_markers, _ = xyz.shape
    n_cam = len(dlts)
    visible = rng.random((n_fields, n_markers, n_cam)) < p_visible
    w, h = SIZE_PX
    rows_f, rows_c, rows_uv, rows_m = [], [], [], []
    leds = rng.random((n_cam, n_leds, 2)) * [w - 1, h - 1]
    for c in range(n_cam):
        uv = project(dlts[c], xyz) + rng.normal(0, noise_px, (n_fields, n_markers, 2))
        inside = (uv[..., 0] >= 0) & (uv[..., 0] < w) & (uv[..., 1] >= 0) & (uv[..., 1] < h)
        visible[..., c] &= inside
        f, m = np.nonzero(visible[..., c])
        rows_f.append(f)
        rows_c.append(np.full(len(f), c))
        rows_uv.append(uv[f, m])
        rows_m.append(m)
        for _ in range(n_noise):
            rows_f.append(np.arange(n_fields))
            rows_c.append(np.full(n_fields, c))
            rows_uv.append(rng.random((n_fields, 2)) * [w - 1, h - 1])
            rows_m.append(np.full(n_fields, -1))
        for led in leds[c]:
            rows_f.append(np.arange(n_fields))
            rows_c.append(np.full(n_fields, c))
            rows_uv.append(led + rng.normal(0, 0.2, (n_fields, 2)))
            rows_m.append(np.full(n_fields, -1))
    field = np.concatenate(rows_f)
    camera = np.concatenate(rows_c)
    uv = np.concatenate(rows_uv)
    truth = np.concatenate(rows_m)
    # shuffle rows: the stage must not rely on the table's order
    perm = rng.permutation(len(field))
    return field[perm], camera[perm], uv[perm], truth[perm], visible
