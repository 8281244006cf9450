"""Synthetic cameras: pinhole + Brown lens distortion, and the KISS-like six-camera rig.

The KISS lab (Shafiq et al. 2001, section 1) records 752 x 291 pixel video fields at
50 Hz with six cameras around a 1.4 m x 2.4 m x 2 m control volume. A field holds every
other line of a 4:3 frame, so pixels are about twice as tall as they are wide: the
principal distances differ (``fy / fx = (4/752) / (3/291) ~ 0.516``). The DLT absorbs that.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.dlt.model import dlt_from_krt

#: Width and height of a KISS video field in pixels.
FIELD_SIZE_PX: tuple[int, int] = (752, 291)
#: Principal distance ratio fy / fx of a 4:3 frame split into 752 x 291 fields.
PIXEL_ASPECT: float = (4.0 / 752.0) / (3.0 / 291.0)
#: Control volume (min, max) corners in lab millimetres: 2.4 m along the walkway (X),
#: 1.4 m across (Y), 2 m high (Z).
VOLUME_MM: tuple[tuple[float, float, float], tuple[float, float, float]] = (
    (-1200.0, -700.0, 0.0),
    (1200.0, 700.0, 2000.0),
)


@dataclass(frozen=True)
class LensDistortion:
    """Brown-Conrady distortion on normalised image coordinates (OpenCV's convention).

    ``x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)`` and
    ``y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y``.
    """

    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    def distort(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Distort normalised coordinates, shape (..., 2)."""
        xy = np.asarray(xy, dtype=float)
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
        yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
        return np.stack([xd, yd], axis=-1)

    def jacobian(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Jacobian d(x_d, y_d)/d(x, y) of :meth:`distort`, shape (..., 2, 2)."""
        xy = np.asarray(xy, dtype=float)
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        dradial_dr2 = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3)
        jac = np.empty((*x.shape, 2, 2))
        jac[..., 0, 0] = radial + 2 * x * x * dradial_dr2 + 2 * self.p1 * y + 6 * self.p2 * x
        jac[..., 0, 1] = 2 * x * y * dradial_dr2 + 2 * self.p1 * x + 2 * self.p2 * y
        jac[..., 1, 0] = 2 * x * y * dradial_dr2 + 2 * self.p1 * x + 2 * self.p2 * y
        jac[..., 1, 1] = radial + 2 * y * y * dradial_dr2 + 6 * self.p1 * y + 2 * self.p2 * x
        return jac

    def undistort(self, xy_d: ArrayLike, iterations: int = 20) -> NDArray[np.float64]:
        """Invert :meth:`distort` by Newton iteration (converges to ~1e-14 for lab lenses)."""
        xy_d = np.asarray(xy_d, dtype=float)
        xy = xy_d.copy()
        for _ in range(iterations):
            err = self.distort(xy) - xy_d
            step = np.linalg.solve(self.jacobian(xy), err[..., None])[..., 0]
            xy = xy - step
            if np.max(np.abs(step), initial=0.0) < 1e-15:
                break
        return xy

    def as_dict(self) -> dict[str, float]:
        return {"k1": self.k1, "k2": self.k2, "k3": self.k3, "p1": self.p1, "p2": self.p2}


@dataclass(frozen=True)
class SynthCamera:
    """A pinhole camera with lens distortion: ``x_cam = R X + t``, pixels ``K distort(x/z)``.

    Attributes
    ----------
    id : str
        Camera name as used in the session (``cam1`` ...).
    size_px : tuple of int
        Image width and height in pixels.
    K : ndarray, shape (3, 3)
        Intrinsics (zero skew), pixels; the principal point uses the DESIGN.md origin
        (centre of the top-left pixel).
    R, t : ndarray
        Lab-to-camera rotation (rows: image right, image down, optical axis) and translation (mm).
    lens : LensDistortion
        Lens distortion on normalised coordinates.
    """

    id: str
    size_px: tuple[int, int]
    K: NDArray[np.float64]
    R: NDArray[np.float64]
    t: NDArray[np.float64]
    lens: LensDistortion = field(default_factory=LensDistortion)

    @property
    def centre_mm(self) -> NDArray[np.float64]:
        """Projection centre in lab millimetres."""
        return -self.R.T @ self.t

    @property
    def dlt(self) -> NDArray[np.float64]:
        """DLT parameters L1..L11 of the undistorted pinhole (maps lab mm to ideal pixels)."""
        return dlt_from_krt(self.K, self.R, self.t)

    def to_camera(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Lab millimetres to camera-frame millimetres, shape (..., 3)."""
        return np.asarray(xyz_mm, dtype=float) @ self.R.T + self.t

    def normalised_to_px(self, xy: ArrayLike) -> NDArray[np.float64]:
        xy = np.asarray(xy, dtype=float)
        u = self.K[0, 0] * xy[..., 0] + self.K[0, 1] * xy[..., 1] + self.K[0, 2]
        v = self.K[1, 1] * xy[..., 1] + self.K[1, 2]
        return np.stack([u, v], axis=-1)

    def px_to_normalised(self, uv: ArrayLike) -> NDArray[np.float64]:
        uv = np.asarray(uv, dtype=float)
        y = (uv[..., 1] - self.K[1, 2]) / self.K[1, 1]
        x = (uv[..., 0] - self.K[0, 2] - self.K[0, 1] * y) / self.K[0, 0]
        return np.stack([x, y], axis=-1)

    def project_ideal(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Undistorted (ideal pinhole) pixel coordinates of lab points."""
        pc = self.to_camera(xyz_mm)
        return self.normalised_to_px(pc[..., :2] / pc[..., 2:3])

    def project(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Distorted pixel coordinates of lab points, as the camera records them."""
        pc = self.to_camera(xyz_mm)
        return self.normalised_to_px(self.lens.distort(pc[..., :2] / pc[..., 2:3]))

    def distort_px(self, uv_ideal: ArrayLike) -> NDArray[np.float64]:
        """Ideal pixel coordinates to the distorted ones the camera records."""
        return self.normalised_to_px(self.lens.distort(self.px_to_normalised(uv_ideal)))

    def undistort_px(self, uv: ArrayLike) -> NDArray[np.float64]:
        """Recorded (distorted) pixel coordinates to ideal pinhole ones."""
        return self.normalised_to_px(self.lens.undistort(self.px_to_normalised(uv)))

    def depth_mm(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Distance along the optical axis (negative behind the camera)."""
        return self.to_camera(xyz_mm)[..., 2]

    def in_image(self, uv: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        uv = np.asarray(uv, dtype=float)
        w, h = self.size_px
        return (
            (uv[..., 0] >= margin_px - 0.5)
            & (uv[..., 0] <= w - 0.5 - margin_px)
            & (uv[..., 1] >= margin_px - 0.5)
            & (uv[..., 1] <= h - 0.5 - margin_px)
        )

    def as_dict(self) -> dict[str, object]:
        """JSON-ready description, as written to ``truth/cameras.json``."""
        return {
            "id": self.id,
            "size": list(self.size_px),
            "K": self.K.tolist(),
            "R": self.R.tolist(),
            "t": self.t.tolist(),
            "centre_mm": self.centre_mm.tolist(),
            "dlt": self.dlt.tolist(),
            "distortion": self.lens.as_dict(),
        }

    @classmethod
    def from_dict(cls, d: dict) -> SynthCamera:
        return cls(
            id=str(d["id"]),
            size_px=(int(d["size"][0]), int(d["size"][1])),
            K=np.asarray(d["K"], dtype=float),
            R=np.asarray(d["R"], dtype=float),
            t=np.asarray(d["t"], dtype=float),
            lens=LensDistortion(**{k: float(v) for k, v in d["distortion"].items()}),
        )


def look_at(centre_mm: ArrayLike, target_mm: ArrayLike, roll_deg: float = 0.0) -> NDArray:
    """Rotation of a level camera at ``centre_mm`` looking at ``target_mm`` (lab Z up).

    Rows are the camera's image-right, image-down and viewing directions in lab axes.
    """
    c = np.asarray(centre_mm, dtype=float)
    forward = np.asarray(target_mm, dtype=float) - c
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    a = np.radians(roll_deg)
    right, down = np.cos(a) * right + np.sin(a) * down, -np.sin(a) * right + np.cos(a) * down
    return np.vstack([right, down, forward])


def volume_corners_mm() -> NDArray[np.float64]:
    lo, hi = np.asarray(VOLUME_MM[0]), np.asarray(VOLUME_MM[1])
    idx = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    return np.where(idx == 1, hi, lo)


# Nominal KISS-like placement: three cameras on each side of the walkway (lab X), in an
# order that alternates sides so that any first n cameras surround the volume.
_NOMINAL_CENTRES_MM = np.array(
    [
        [-2600.0, -4000.0, 1700.0],
        [0.0, 4300.0, 1800.0],
        [2600.0, -4000.0, 1700.0],
        [-2600.0, 4000.0, 1700.0],
        [0.0, -4300.0, 1800.0],
        [2600.0, 4000.0, 1700.0],
    ]
)


def kiss_rig(
    seed: int = 1,
    n_cameras: int = 6,
    corner_distortion_px: tuple[float, float] = (6.0, 9.0),
    fill: float = 0.95,
) -> tuple[SynthCamera, ...]:
    """The KISS-like rig: up to six cameras around the 1.4 x 2.4 x 2 m volume.

    Parameters
    ----------
    seed : int
        Positions, aim points, roll, principal points and lenses vary with the seed.
    n_cameras : int
        2 to 6; the first ``n`` of an order that alternates the two sides of the walkway.
    corner_distortion_px : (float, float)
        Range of the lens distortion displacement at the image corners, in pixels.
    fill : float
        Fraction of the image half-size that the control volume fills at most.

    Returns
    -------
    tuple of SynthCamera
        Cameras ``cam1`` ... ``camN``; every one sees the whole control volume.
    """
    if not 2 <= n_cameras <= len(_NOMINAL_CENTRES_MM):
        raise ValueError(f"n_cameras must be 2..6, got {n_cameras}")
    rng = np.random.default_rng([seed, 1001])
    w, h = FIELD_SIZE_PX
    corners = volume_corners_mm()
    cams = []
    for i in range(n_cameras):
        centre = _NOMINAL_CENTRES_MM[i] + rng.uniform(-150, 150, 3) * [1, 1, 0.5]
        target = np.array([0.0, 0.0, 1000.0]) + rng.uniform(-80, 80, 3)
        R = look_at(centre, target, roll_deg=rng.uniform(-1.5, 1.5))
        t = -R @ centre
        cx = (w - 1) / 2 + rng.normal(0, 6)
        cy = (h - 1) / 2 + rng.normal(0, 3)
        # Principal distance: the largest that keeps the whole volume inside `fill`.
        pc = corners @ R.T + t
        xn, yn = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
        room_x = np.where(xn > 0, (w - 1 - cx), cx) * fill
        room_y = np.where(yn > 0, (h - 1 - cy), cy) * fill
        fx = min(np.min(room_x / np.abs(xn)), np.min(room_y / (PIXEL_ASPECT * np.abs(yn))))
        K = np.array([[fx, 0.0, cx], [0.0, fx * PIXEL_ASPECT, cy], [0.0, 0.0, 1.0]])
        lens = _barrel_lens(rng, K, (w, h), corner_distortion_px)
        cams.append(SynthCamera(f"cam{i + 1}", (w, h), K, R, t, lens))
    return tuple(cams)


def _barrel_lens(
    rng: np.random.Generator,
    K: NDArray,
    size_px: tuple[int, int],
    corner_px: tuple[float, float],
) -> LensDistortion:
    """A barrel lens (as in the seed's Fig. 10) whose corner displacement is in ``corner_px``."""
    w, h = size_px
    corners = np.array([[0.0, 0.0], [w - 1, 0.0], [0.0, h - 1], [w - 1, h - 1]])
    xn = (corners[:, 0] - K[0, 2]) / K[0, 0]
    yn = (corners[:, 1] - K[1, 2]) / K[1, 1]
    r2 = xn**2 + yn**2
    dist_px = np.hypot(corners[:, 0] - K[0, 2], corners[:, 1] - K[1, 2])
    target = rng.uniform(*corner_px)
    k1 = -target / np.max(r2 * dist_px)
    k2 = rng.uniform(-0.2, 0.2) * abs(k1)
    p1, p2 = rng.uniform(-2e-4, 2e-4, 2)
    return LensDistortion(k1=k1, k2=k2, p1=p1, p2=p2)
