"""DLT stage speed, as ratios against the seeds' plain pseudo-inverse DLT timed in the same run.

Reference: the 11-unknown least squares of Küçük eq. 2.13 / Kolahi eq. 9 on raw
coordinates (``numpy.linalg.lstsq``), which is what the linear DLT costs at minimum.
"""

from __future__ import annotations

import numpy as np

from benchmarks._harness import best_of, report
from kisscal.dlt import (
    DltParams,
    calibrate_camera,
    compose_dlt,
    make_rods,
    project,
    recognise_rods,
    triangulate_dlt,
)
from kisscal.errors import KisscalError

ROD_Z_MM = (
    [1900, 1660, 1440, 680, 530, 100],
    [1900, 1640, 1210, 1000, 680, 100],
    [1900, 1660, 1050, 560, 330, 100],
    [1900, 1550, 1240, 910, 680, 100],
)
ROD_XY_MM = ((0, 0), (2400, 0), (2400, 1400), (0, 1400))


def _camera(x_mm: float = -900.0, y_mm: float = -3500.0) -> np.ndarray:
    K = np.array([[720.0, 0, 376], [0, 374, 145], [0, 0, 1]])
    C = np.array([x_mm, y_mm, 1100])
    z = np.array([1200.0, 700, 1000]) - C
    z /= np.linalg.norm(z)
    x = np.cross(z, [0, 0, 1.0])
    x /= np.linalg.norm(x)
    return compose_dlt(K, np.array([x, np.cross(z, x), z]), C)


def _pinv_dlt(xyz: np.ndarray, uv: np.ndarray) -> np.ndarray:
    n = len(xyz)
    A = np.zeros((2 * n, 11))
    A[0::2, 0:3], A[0::2, 3] = xyz, 1
    A[1::2, 4:7], A[1::2, 7] = xyz, 1
    A[0::2, 8:11] = -uv[:, :1] * xyz
    A[1::2, 8:11] = -uv[:, 1:] * xyz
    return np.linalg.lstsq(A, uv.ravel(), rcond=None)[0]


def _refused(blobs: np.ndarray, rods: tuple) -> bool:
    try:
        recognise_rods(blobs, rods)
    except KisscalError:
        return True
    return False


def main() -> list[str]:
    rng = np.random.default_rng(0)
    rods = make_rods(
        [(f"R{i + 1}", [[*ROD_XY_MM[i], z] for z in zs]) for i, zs in enumerate(ROD_Z_MM)]
    )
    xyz = np.concatenate([r.points_mm for r in rods])
    L = _camera()
    uv = project(L, xyz) + rng.normal(0, 0.05, (24, 2))
    blobs = np.concatenate([uv, rng.uniform([0, 0], [751, 290], (8, 2))])
    ref = best_of("pinv DLT (raw coords, 24 pts)", lambda: _pinv_dlt(xyz, uv), 1, "cam", 50)
    lines = [report(ref)]
    for name, p in [
        ("solve DLT (normalised)", DltParams()),
        ("MDLT", DltParams(mdlt=True)),
        ("refined", DltParams(refine=True)),
        ("MDLT + refined", DltParams(mdlt=True, refine=True)),
        ("refined + lens L12-L16", DltParams(lens=True)),
    ]:
        t = best_of(name, lambda p=p: calibrate_camera(xyz, uv, p), 1, "cam", 10)
        lines.append(report(t, ref))
    t = best_of("recognise rods (32 blobs)", lambda: recognise_rods(blobs, rods), 1, "image", 5)
    lines.append(report(t, ref))
    # a busy image the search still takes on, and a hopeless one it refuses up front
    busy = np.concatenate([blobs, rng.uniform([0, 0], [751, 290], (60, 2))])
    t = best_of("recognise rods (92 blobs)", lambda: _refused(busy, rods), 1, "image", 3)
    lines.append(report(t, ref))
    clutter = np.concatenate([blobs, rng.uniform([0, 0], [751, 290], (1300, 2))])
    t = best_of("refuse a rod image (1332 blobs)", lambda: _refused(clutter, rods), 1, "image", 3)
    lines.append(report(t, ref))
    Ls = np.stack([_camera(x, y) for x in (-900, 1200, 3300) for y in (-3500, 4900)])
    pts = rng.uniform([0, 0, 0], [2400, 1400, 2000], (10000, 3))
    puv = np.stack([project(Lc, pts) for Lc in Ls])
    t = best_of("triangulate 6 cams", lambda: triangulate_dlt(Ls, puv), 10000, "pt", 3)
    lines.append(report(t, ref))
    return lines
