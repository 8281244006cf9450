"""Synthetic cameras (:class:`kisscal.camera.Camera`, Brown's lens) and the KISS-like rig.

The KISS lab (Shafiq et al. 2001, section 1) records 752 x 291 pixel video fields at
50 Hz with six cameras around a 1.4 m x 2.4 m x 2 m control volume. A field holds every
other line of a 4:3 frame, so pixels are about twice as tall as they are wide: the
principal distances differ (``fy / fx = (4/752) / (3/291) ~ 0.516``). The DLT absorbs that.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.camera import Camera, undistort

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


def truth_dict(camera: Camera) -> dict[str, object]:
    """A synthetic camera as ``truth/cameras.json`` holds it (JSON-ready)."""
    k1, k2, p1, p2, k3 = (float(v) for v in camera.lens[:5])
    return {
        "id": camera.id,
        "size": list(camera.size_px or ()),
        "K": camera.K.tolist(),
        "R": camera.R.tolist(),
        "t": camera.t.tolist(),
        "centre_mm": camera.centre_mm.tolist(),
        "dlt": camera.dlt.tolist(),
        "distortion": {"k1": k1, "k2": k2, "k3": k3, "p1": p1, "p2": p2},
    }


def brown_lens(
    k1: float = 0.0, k2: float = 0.0, k3: float = 0.0, p1: float = 0.0, p2: float = 0.0
) -> NDArray[np.float64]:
    """Brown's terms by name, as the vector a :class:`~kisscal.camera.Camera` holds."""
    return np.array([k1, k2, p1, p2, k3])


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
) -> tuple[Camera, ...]:
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
    tuple of Camera
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
        cams.append(Camera(K, R, t, lens, f"cam{i + 1}", (w, h)))
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
    pixel_aspect: float = 1.0,
    start_deg: tuple[float, float] | None = None,
) -> tuple[Camera, ...]:
    """Cameras evenly spaced on a ring around the volume, all aimed at it.

    The ring is an ellipse ``clearance_mm`` outside the volume's footprint; azimuths are
    evenly spaced from a seed-drawn start, each jittered by up to a tenth of the spacing;
    heights alternate between the low and the high half of ``height_mm``. Every camera
    sees the whole volume (its principal distance is the largest that keeps it within 95 %
    of the way to each image edge).
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
        K = fitted_intrinsics(R, t, size_px, principal, 1.0 / pixel_aspect, corners, 0.95)
        lens = _barrel_lens(rng, K, size_px, corner_distortion_px, exact=True)
        cams.append(Camera(K, R, t, lens, f"cam{i + 1}", size_px))
    return tuple(cams)


def _barrel_lens(
    rng: np.random.Generator,
    K: NDArray,
    size_px: tuple[int, int],
    corner_px: tuple[float, float],
    exact: bool = False,
) -> NDArray[np.float64]:
    """Brown's terms of a barrel lens (the seed's Fig. 10), its corner shift in ``corner_px``.

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
    # A draw, not a lens model: under k1 = 1 a corner moves r² times its distance (first
    # order), so this k1 moves the farthest corner by the drawn target.
    shift_per_k1_px = r2 * dist_px
    k1 = -target / np.max(shift_per_k1_px)
    k2 = rng.uniform(-0.2, 0.2) * abs(k1)
    if exact:  # the r^4 term at most a fifth of the r^2 term at the corners, as in KISS
        k2 /= np.max(r2)
    p1, p2 = rng.uniform(-2e-4, 2e-4, 2)
    lens = brown_lens(k1=k1, k2=k2, p1=p1, p2=p2)
    for _ in range(3 if exact else 0):
        ideal = np.column_stack([xn, yn])
        shift = np.linalg.norm((undistort(lens, ideal) - ideal) * [K[0, 0], K[1, 1]], axis=1)
        scale = target / shift.min()
        lens = brown_lens(k1=lens[0] * scale, k2=lens[1] * scale, p1=p1, p2=p2)
    return lens
