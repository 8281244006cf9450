"""OpenPTV's camera model, to compare kisscal's target calibration with OpenPTV's own.

OpenPTV (Maas 1996; liboptv) calibrates each camera of a particle-tracking rig that looks
through a flat glass wall into water. Its projection of a lab point, as its calibration
files describe it:

1. **Refraction** (Maas 1996, "multimedia geometry"): the point is replaced by the point
   at the same depth that a straight ray from the camera would reach, so that the rest is
   a pinhole. The glass wall is a plane perpendicular to the ``.ori`` file's glass vector,
   at its length from the origin (water beyond it), ``d`` mm thick towards the camera;
   refractive indices air ``n1``, glass ``n2``, water ``n3`` (``ptv.par``). The ray's
   radius at the point's depth follows from Snell's law through the three layers, solved
   here by the fixed-point iteration OpenPTV uses, to 1e-9 mm.
2. **Pinhole** in mm: ``x = -c (r1 . (X - X0)) / (r3 . (X - X0))`` with ``r_i`` the
   columns of the ``.ori`` rotation matrix and ``c`` the principal distance, then the
   principal point ``(xh, yh)`` added.
3. **Brown distortion and affine terms** (``.addpar``: k1 k2 k3 p1 p2 scx she; Brown
   1971) on those mm coordinates, in OpenPTV's order of the decentring terms.
4. **Pixels**: ``u = x / pix + w / 2``, ``v = h / 2 - y / pix`` with the origin at the
   corner of the top-left pixel; kisscal's origin is that pixel's centre, so 0.5 px is
   subtracted.

References
----------
Maas, H.-G. (1996). Contributions of digital photogrammetry to 3-D PTV. In Dracos, T.
(ed.), Three-Dimensional Velocity and Vorticity Measuring and Image Analysis Techniques.
Brown, D. C. (1971). Close-range camera calibration. Photogramm. Eng. 37(8).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Multimedia:
    """Refractive indices of air, glass and water, and the glass thickness (mm)."""

    n_air: float
    n_glass: float
    n_water: float
    glass_mm: float


@dataclass(frozen=True)
class OpenPtvCamera:
    """One camera of an OpenPTV calibration (``.ori`` + ``.addpar`` + ``ptv.par``)."""

    centre_mm: NDArray[np.float64]
    dm: NDArray[np.float64]  # rotation matrix as the .ori file lists it
    xh_mm: float
    yh_mm: float
    c_mm: float
    glass_vec_mm: NDArray[np.float64]
    added: NDArray[np.float64]  # k1 k2 k3 p1 p2 scx she
    media: Multimedia
    size_px: tuple[int, int]
    pixel_mm: float


def read_ptv_par(path: Path) -> tuple[tuple[int, int], float, Multimedia]:
    """Image size (px), pixel size (mm) and the media of OpenPTV's ``ptv.par``."""
    lines = [s.strip() for s in Path(path).read_text().split("\n") if s.strip()]
    n_cam = int(lines[0])
    rest = lines[1 + 2 * n_cam :]  # after each camera's image and calibration image names
    # hp_flag, allcam_flag, tiff_flag, imx, imy, pix_x, pix_y, chfield, n1, n2, n3, d
    size = (int(rest[3]), int(rest[4]))
    pixel = float(rest[5])
    media = Multimedia(float(rest[8]), float(rest[9]), float(rest[10]), float(rest[11]))
    return size, pixel, media


def read_camera(ori: Path, addpar: Path, ptv_par: Path) -> OpenPtvCamera:
    """One camera from its ``.ori`` and ``.addpar`` files and the rig's ``ptv.par``."""
    v = np.array(Path(ori).read_text().split(), dtype=float)
    size, pixel, media = read_ptv_par(ptv_par)
    added = np.array(Path(addpar).read_text().split(), dtype=float)
    # .ori: X0 Y0 Z0, omega phi kappa, the 3 x 3 matrix, xh yh, c, glass vector
    return OpenPtvCamera(
        v[0:3], v[6:15].reshape(3, 3), v[15], v[16], v[17], v[18:21], added, media, size, pixel
    )


def _virtual_points(cam: OpenPtvCamera, xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each point moved, at its depth, to where a straight ray from the camera meets it."""
    m = cam.media
    if m.n_air == m.n_glass == m.n_water == 1.0:
        return xyz
    g_len = float(np.linalg.norm(cam.glass_vec_mm))
    g = cam.glass_vec_mm / g_len
    height = float(cam.centre_mm @ g) - g_len  # camera above the water-side face
    depth = xyz @ g - g_len  # points: negative beyond the face, in the water
    across = (xyz - cam.centre_mm) - np.outer((xyz - cam.centre_mm) @ g, g)
    r = np.linalg.norm(across, axis=1)
    rq = r.copy()
    for _ in range(200):
        b1 = np.arctan(rq / (height - depth))
        b2 = np.arcsin(np.sin(b1) * m.n_air / m.n_glass)
        b3 = np.arcsin(np.sin(b1) * m.n_air / m.n_water)
        reach = (height - m.glass_mm) * np.tan(b1) + m.glass_mm * np.tan(b2) - depth * np.tan(b3)
        step = r - reach
        rq = rq + step
        if np.max(np.abs(step)) < 1e-9:
            break
    scale = np.divide(rq, r, out=np.ones_like(r), where=r > 0)
    return xyz + across * (scale - 1.0)[:, None]


def project(cam: OpenPtvCamera, xyz_mm: NDArray[np.float64]) -> NDArray[np.float64]:
    """kisscal pixels (origin at the top-left pixel's centre) of lab points, shape (n, 2)."""
    xyz = _virtual_points(cam, np.asarray(xyz_mm, dtype=float).reshape(-1, 3))
    d = (xyz - cam.centre_mm) @ cam.dm  # columns of the .ori matrix
    x = -cam.c_mm * d[:, 0] / d[:, 2] + cam.xh_mm
    y = -cam.c_mm * d[:, 1] / d[:, 2] + cam.yh_mm
    k1, k2, k3, p1, p2, scx, she = cam.added
    r2 = x * x + y * y
    radial = k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x + x * radial + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y
    yd = y + y * radial + p2 * (r2 + 2 * y * y) + 2 * p1 * x * y
    x, y = scx * xd - np.sin(she) * yd, np.cos(she) * yd
    w, h = cam.size_px
    u = x / cam.pixel_mm + w / 2.0
    v = h / 2.0 - y / cam.pixel_mm
    return np.column_stack([u, v]) - 0.5
