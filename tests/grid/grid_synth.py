"""Controlled synthetic grid views for the grid stage tests (independent of kisscal.synth).

A pinhole camera with non-square pixels (fy = 0.52 fx, like the 752 x 291 KISS fields)
and Brown radial + tangential distortion views a 15 x 20 dot grid at close range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BrownCamera:
    """Pinhole + Brown distortion, pixel coordinates with origin at the top-left pixel."""

    fx: float = 800.0
    fy: float = 416.0
    cx: float = 375.5
    cy: float = 145.0
    k1: float = -0.05
    k2: float = 0.01
    k3: float = 0.0
    p1: float = 4e-4
    p2: float = -3e-4
    size_px: tuple[int, int] = (752, 291)

    def distort_px(self, uv_ideal: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv_ideal, dtype=float)
        x = (uv[..., 0] - self.cx) / self.fx
        y = (uv[..., 1] - self.cy) / self.fy
        r2 = x * x + y * y
        radial = 1 + self.k1 * r2 + self.k2 * r2**2 + self.k3 * r2**3
        xd = x * radial + 2 * self.p1 * x * y + self.p2 * (r2 + 2 * x * x)
        yd = y * radial + self.p1 * (r2 + 2 * y * y) + 2 * self.p2 * x * y
        return np.stack([xd * self.fx + self.cx, yd * self.fy + self.cy], axis=-1)

    def project_ideal(self, xyz_cam: np.ndarray) -> np.ndarray:
        xyz = np.asarray(xyz_cam, dtype=float)
        return np.stack(
            [
                self.fx * xyz[..., 0] / xyz[..., 2] + self.cx,
                self.fy * xyz[..., 1] / xyz[..., 2] + self.cy,
            ],
            axis=-1,
        )


def _rot(ax: float, ay: float, az: float) -> np.ndarray:
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


@dataclass(frozen=True)
class GridView:
    camera: BrownCamera
    row: np.ndarray
    col: np.ndarray
    ideal_uv: np.ndarray
    distorted_uv: np.ndarray  # noise-free
    dots_uv: np.ndarray  # with centroid noise


def make_grid_view(
    seed: int = 0,
    *,
    rows: int = 15,
    cols: int = 20,
    roll_deg: float = 3.0,
    tilt_deg: tuple[float, float] = (2.0, -1.5),
    pitch_over_z: float = 0.0455,
    offset_px: tuple[float, float] = (4.0, -3.0),
    noise_px: float = 0.05,
    camera: BrownCamera | None = None,
) -> GridView:
    """A grid of rows x cols dots seen by ``camera``, tilted and rolled a few degrees."""
    cam = camera or BrownCamera()
    rng = np.random.default_rng(seed)
    rr, cc = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    row, col = rr.ravel(), cc.ravel()
    z = 1000.0
    pitch = pitch_over_z * z
    obj = np.column_stack(
        [(col - (cols - 1) / 2) * pitch, (row - (rows - 1) / 2) * pitch, np.zeros(row.size)]
    )
    r = _rot(np.radians(tilt_deg[0]), np.radians(tilt_deg[1]), np.radians(roll_deg))
    shift = np.array([offset_px[0] / cam.fx * z, offset_px[1] / cam.fy * z, z])
    xyz = obj @ r.T + shift
    ideal = cam.project_ideal(xyz)
    dist = cam.distort_px(ideal)
    dots = dist + rng.normal(0.0, noise_px, dist.shape)
    return GridView(cam, row, col, ideal, dist, dots)


def fit_similarity(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Least-squares similarity src -> dst (complex-number form), returns mapped src."""
    s = src[:, 0] + 1j * src[:, 1]
    d = dst[:, 0] + 1j * dst[:, 1]
    a = np.column_stack([s, np.ones_like(s)])
    coef, *_ = np.linalg.lstsq(a, d, rcond=None)
    m = a @ coef
    return np.column_stack([m.real, m.imag])


def rms(d: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(np.asarray(d) ** 2, axis=-1))))
