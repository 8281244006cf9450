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


def volume_corners_mm(
    volume_mm: tuple[tuple[float, float, float], tuple[float, float, float]] = VOLUME_MM,
) -> NDArray[np.float64]:
    """The eight corners of a control volume ``(min, max)``, lab millimetres, shape (8, 3)."""
    lo, hi = np.asarray(volume_mm[0], dtype=float), np.asarray(volume_mm[1], dtype=float)
    idx = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    return np.where(idx == 1, hi, lo)


# Nominal KISS-like placement: three cameras on each side of the walkway (lab X), in an
# order that alternates sides so that any first n cameras surround the volume. Cameras 7
# to 16 (beyond the KISS lab's six) stand at the ends of the walkway, between the side
# cameras and at the corners, again alternating.
_NOMINAL_CENTRES_MM = np.array(
    [
        [-2600.0, -4000.0, 1700.0],
        [0.0, 4300.0, 1800.0],
        [2600.0, -4000.0, 1700.0],
        [-2600.0, 4000.0, 1700.0],
        [0.0, -4300.0, 1800.0],
        [2600.0, 4000.0, 1700.0],
        [-4800.0, 0.0, 2000.0],
        [4800.0, 0.0, 2000.0],
        [-1300.0, -4200.0, 2300.0],
        [1300.0, 4200.0, 2300.0],
        [1300.0, -4200.0, 2300.0],
        [-1300.0, 4200.0, 2300.0],
        [-4200.0, -2600.0, 1500.0],
        [4200.0, 2600.0, 1500.0],
        [4200.0, -2600.0, 1500.0],
        [-4200.0, 2600.0, 1500.0],
    ]
)
#: Most cameras a synthetic rig has.
MAX_CAMERAS = len(_NOMINAL_CENTRES_MM)


def kiss_rig(
    seed: int = 1,
    n_cameras: int = 6,
    corner_distortion_px: tuple[float, float] = (6.0, 9.0),
    fill: float = 0.95,
) -> tuple[SynthCamera, ...]:
    """The KISS-like rig: six cameras (up to 16) around the 1.4 x 2.4 x 2 m volume.

    Parameters
    ----------
    seed : int
        Positions, aim points, roll, principal points and lenses vary with the seed.
    n_cameras : int
        2 to 16; the first ``n`` of an order that alternates the two sides of the walkway
        (the first six are the KISS lab's; a rig of ``n`` cameras is the first ``n`` of a
        larger one of the same seed).
    corner_distortion_px : (float, float)
        Range of the lens distortion displacement at the image corners, in pixels.
    fill : float
        Fraction of the image half-size that the control volume fills at most.

    Returns
    -------
    tuple of SynthCamera
        Cameras ``cam1`` ... ``camN``; every one sees the whole control volume.
    """
    if not 2 <= n_cameras <= MAX_CAMERAS:
        raise ValueError(f"n_cameras must be 2..{MAX_CAMERAS}, got {n_cameras}")
    rng = np.random.default_rng([seed, 1001])
    w, h = FIELD_SIZE_PX
    corners = volume_corners_mm()
    cams = []
    for i in range(n_cameras):
        centre = _NOMINAL_CENTRES_MM[i] + rng.uniform(-150, 150, 3) * [1, 1, 0.5]
        target = np.array([0.0, 0.0, 1000.0]) + rng.uniform(-80, 80, 3)
        R = look_at(centre, target, roll_deg=rng.uniform(-1.5, 1.5))
        cx = (w - 1) / 2 + rng.normal(0, 6)
        cy = (h - 1) / 2 + rng.normal(0, 3)
        t = -R @ centre
        K = fitted_intrinsics(R, t, (w, h), (cx, cy), PIXEL_ASPECT, corners, fill)
        lens = _barrel_lens(rng, K, (w, h), corner_distortion_px)
        cams.append(SynthCamera(f"cam{i + 1}", (w, h), K, R, t, lens))
    return tuple(cams)


def fitted_intrinsics(
    R: NDArray[np.float64],
    t: NDArray[np.float64],
    size_px: tuple[int, int],
    principal_px: tuple[float, float],
    fy_per_fx: float,
    points_mm: NDArray[np.float64],
    fill: float,
) -> NDArray[np.float64]:
    """Intrinsics with the largest principal distance that keeps ``points_mm`` inside ``fill``.

    ``fill`` is the fraction of the distance from the principal point to each image edge
    that the points may use; ``fy = fy_per_fx * fx`` (fewer, taller rows: below 1).
    """
    w, h = size_px
    cx, cy = principal_px
    pc = np.asarray(points_mm, dtype=float) @ R.T + t
    xn, yn = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
    room_x = np.where(xn > 0, (w - 1 - cx), cx) * fill
    room_y = np.where(yn > 0, (h - 1 - cy), cy) * fill
    fx = min(np.min(room_x / np.abs(xn)), np.min(room_y / (fy_per_fx * np.abs(yn))))
    return np.array([[fx, 0.0, cx], [0.0, fx * fy_per_fx, cy], [0.0, 0.0, 1.0]])


def ring_rig(
    seed: int,
    n_cameras: int,
    size_px: tuple[int, int],
    volume_mm: tuple[tuple[float, float, float], tuple[float, float, float]],
    clearance_mm: tuple[float, float],
    height_mm: tuple[float, float],
    corner_distortion_px: tuple[float, float],
    fill: float = 0.95,
    pixel_aspect: float = 1.0,
    start_deg: tuple[float, float] | None = None,
) -> tuple[SynthCamera, ...]:
    """Cameras evenly spaced on a ring around the volume, all aimed at it.

    The ring is an ellipse ``clearance_mm`` outside the volume's footprint; azimuths are
    evenly spaced from a seed-drawn start, each jittered by up to a tenth of the spacing;
    heights alternate between the low and the high half of ``height_mm``. Every camera
    sees the whole volume (its principal distance is the largest that does).
    ``pixel_aspect`` is a pixel's height / width (``fx / fy``; 1: square pixels).
    ``start_deg`` is the range of the first camera's azimuth (degrees from lab +X, the
    walkway); by default anywhere within one spacing.

    Examples
    --------
    >>> rig = ring_rig(1, 8, (1280, 1024), ((-2000, -1000, 0), (2000, 1000, 2000)),
    ...                (3000, 4000), (2200, 3000), (2, 6))
    >>> [c.id for c in rig][-1], all(c.in_image(c.project(volume_corners_mm(
    ...     ((-2000, -1000, 0), (2000, 1000, 2000))))).all() for c in rig)
    ('cam8', True)
    """
    if not 2 <= n_cameras <= MAX_CAMERAS:
        raise ValueError(f"n_cameras must be 2..{MAX_CAMERAS}, got {n_cameras}")
    rng = np.random.default_rng([seed, 1002])
    lo, hi = np.asarray(volume_mm[0], dtype=float), np.asarray(volume_mm[1], dtype=float)
    half, middle = (hi - lo) / 2, (hi + lo) / 2
    corners = volume_corners_mm(volume_mm)
    w, h = size_px
    spacing = 2 * np.pi / n_cameras
    start = rng.uniform(0, spacing) if start_deg is None else np.radians(rng.uniform(*start_deg))
    mid_height = 0.5 * (height_mm[0] + height_mm[1])
    cams = []
    for i in range(n_cameras):
        azimuth = start + i * spacing + rng.uniform(-0.1, 0.1) * spacing
        clearance = rng.uniform(*clearance_mm)
        band = (height_mm[0], mid_height) if i % 2 == 0 else (mid_height, height_mm[1])
        centre = np.array(
            [
                middle[0] + (half[0] + clearance) * np.cos(azimuth),
                middle[1] + (half[1] + clearance) * np.sin(azimuth),
                rng.uniform(*band),
            ]
        )
        target = middle * [1, 1, 0.9] + rng.uniform(-1, 1, 3) * [0.05, 0.05, 0.05] * half
        R = look_at(centre, target, roll_deg=rng.uniform(-2.0, 2.0))
        principal = ((w - 1) / 2 + rng.normal(0, 0.004 * w), (h - 1) / 2 + rng.normal(0, 0.004 * h))
        t = -R @ centre
        K = fitted_intrinsics(R, t, size_px, principal, 1.0 / pixel_aspect, corners, fill)
        lens = _barrel_lens(rng, K, size_px, corner_distortion_px, exact=True)
        cams.append(SynthCamera(f"cam{i + 1}", size_px, K, R, t, lens))
    return tuple(cams)


def _barrel_lens(
    rng: np.random.Generator,
    K: NDArray,
    size_px: tuple[int, int],
    corner_px: tuple[float, float],
    exact: bool = False,
) -> LensDistortion:
    """A barrel lens (as in the seed's Fig. 10) whose corner displacement is in ``corner_px``.

    The draw targets the largest corner displacement to first order; ``exact`` keeps the
    ``k2`` term within a fifth of the ``k1`` term at the corners (wide-angle lenses reach
    ``r^2 > 1`` there) and then scales the radial terms so that the *smallest*
    displacement of the four corners is the drawn value.
    """
    w, h = size_px
    corners = np.array([[0.0, 0.0], [w - 1, 0.0], [0.0, h - 1], [w - 1, h - 1]])
    xn = (corners[:, 0] - K[0, 2]) / K[0, 0]
    yn = (corners[:, 1] - K[1, 2]) / K[1, 1]
    r2 = xn**2 + yn**2
    dist_px = np.hypot(corners[:, 0] - K[0, 2], corners[:, 1] - K[1, 2])
    target = rng.uniform(*corner_px)
    k1 = -target / np.max(r2 * dist_px)
    k2 = rng.uniform(-0.2, 0.2) * abs(k1)
    if exact:  # the r^4 term at most a fifth of the r^2 term at the corners, as in KISS
        k2 /= np.max(r2)
    p1, p2 = rng.uniform(-2e-4, 2e-4, 2)
    lens = LensDistortion(k1=k1, k2=k2, p1=p1, p2=p2)
    for _ in range(3 if exact else 0):
        ideal = np.column_stack([xn, yn])
        shift = np.linalg.norm((lens.undistort(ideal) - ideal) * [K[0, 0], K[1, 1]], axis=1)
        scale = target / shift.min()
        lens = LensDistortion(k1=lens.k1 * scale, k2=lens.k2 * scale, p1=p1, p2=p2)
    return lens
