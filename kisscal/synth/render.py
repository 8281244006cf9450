"""Rendering of 8-bit infrared fields: marker spots, LED rings, noise pixels and streaks.

A retro-reflective sphere images as a bright, nearly uniform elliptical spot (the pixels
are not square). Each spot is drawn with an anti-aliased edge: the grey value is the
fraction of the pixel the ellipse covers, estimated from the signed distance of the
pixel centre to the ellipse boundary. The ellipse is the sphere's outline mapped through
the local Jacobian of the lens distortion, so its centre is exactly the distorted
projection of the sphere's centre: that is the truth centroid.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal.synth.cameras import SynthCamera


@dataclass(frozen=True)
class RenderParams:
    """How a synthetic infrared field looks.

    Attributes
    ----------
    background : float
        Grey level of the dark background.
    noise_sigma : float
        Standard deviation of the Gaussian sensor noise, grey levels. Off by default: the
        KISS cameras' video is thresholded dark, and a noisy background makes every PNG
        incompressible (a session would take ~10x the disk).
    marker_peak : float
        Grey level of a marker spot's plateau.
    bloom_px : float
        Blooming of bright spots: added to the geometric spot radius, pixels.
    blur_px : float
        Sigma of the Gaussian optical blur, pixels (0: none).
    noise_pixels : float
        Mean number of isolated bright noise pixels per field (Poisson).
    streak_probability : float
        Chance that a field holds a one-pixel-wide streak.
    led_radius_mm : float
        Radius of the infrared LED ring around each camera lens.
    """

    background: float = 6.0
    noise_sigma: float = 0.0
    marker_peak: float = 230.0
    bloom_px: float = 0.5
    blur_px: float = 0.6
    noise_pixels: float = 3.0
    streak_probability: float = 0.3
    led_radius_mm: float = 60.0


@dataclass(frozen=True)
class Spots:
    """Elliptical spots to draw: centres (n, 2) in pixels and shape matrices (n, 2, 2).

    ``shape[i]`` maps the unit circle onto spot ``i``'s outline (pixels), so a pixel offset
    ``d`` lies inside when ``|inv(shape[i]) d| <= 1``.
    """

    centre_px: NDArray[np.float64]
    shape: NDArray[np.float64]
    peak: NDArray[np.float64]

    @property
    def radii_px(self) -> NDArray[np.float64]:
        """Half-extent of each spot along image x and y, shape (n, 2)."""
        return np.sqrt(np.sum(self.shape**2, axis=2))


def draw_spots(image: NDArray[np.float64], spots: Spots, supersample: int = 4) -> None:
    """Draw anti-aliased elliptical spots into a float image (in place, overlaps take the max).

    A pixel's grey value is the spot's peak times the fraction of the pixel inside the
    ellipse, estimated on ``supersample`` x ``supersample`` sub-pixels, each of which uses
    the signed distance of its centre to the outline over a ramp one sub-pixel wide. The
    centroid of a rendered spot is then its true centre to about 0.01 px.
    Vectorised over all spots of a field: every spot is evaluated on a patch of the same
    size, and the patches are combined with ``np.maximum.at``.
    """
    n = len(spots.centre_px)
    if n == 0:
        return
    h, w = image.shape
    radii = spots.radii_px
    half = int(np.ceil(radii.max())) + 2
    offs = np.arange(-half, half + 1)
    cu = np.rint(spots.centre_px[:, 0]).astype(int)
    cv = np.rint(spots.centre_px[:, 1]).astype(int)
    px = cu[:, None, None] + offs[None, None, :]  # (n, 1, P)
    py = cv[:, None, None] + offs[None, :, None]  # (n, P, 1)
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    inv = np.linalg.inv(spots.shape)
    coverage = np.zeros((n, len(offs), len(offs)))
    for sy in sub:  # supersample**2 passes, each vectorised over all spots and pixels
        for sx in sub:
            du = px + sx - spots.centre_px[:, 0, None, None]
            dv = py + sy - spots.centre_px[:, 1, None, None]
            a = inv[:, 0, 0, None, None] * du + inv[:, 0, 1, None, None] * dv
            b = inv[:, 1, 0, None, None] * du + inv[:, 1, 1, None, None] * dv
            rho = np.sqrt(a * a + b * b)  # 1 on the outline
            outside_px = np.hypot(du, dv) * (1.0 - 1.0 / np.maximum(rho, 1e-9))
            coverage += np.clip(0.5 - outside_px * supersample, 0.0, 1.0)
    value = coverage / supersample**2 * spots.peak[:, None, None]
    pyb, pxb = np.broadcast_arrays(py, px)
    ok = (pxb >= 0) & (pxb < w) & (pyb >= 0) & (pyb < h) & (value > 0)
    np.maximum.at(image, (pyb[ok], pxb[ok]), value[ok])


def add_noise_pixels(
    image: NDArray[np.float64],
    rng: np.random.Generator,
    params: RenderParams,
    keep_clear_px: NDArray[np.float64],
    clearance_px: float = 8.0,
) -> None:
    """Add isolated bright pixels and, sometimes, a one-pixel-wide streak (in place).

    Noise is kept ``clearance_px`` away from the points in ``keep_clear_px`` (the spots), so
    that truth centroids stay the centroids of the spots alone.
    """
    h, w = image.shape
    n = rng.poisson(params.noise_pixels)
    u = rng.integers(0, w, n)
    v = rng.integers(0, h, n)
    streak = rng.random() < params.streak_probability
    if streak:
        length = int(rng.integers(6, 30))
        if rng.random() < 0.6:  # horizontal streak, one pixel high
            u0, v0 = int(rng.integers(0, w - length)), int(rng.integers(0, h))
            su, sv = np.arange(u0, u0 + length), np.full(length, v0)
        else:  # vertical streak, one pixel wide
            length = min(length, h - 1) // 3
            u0, v0 = int(rng.integers(0, w)), int(rng.integers(0, h - length))
            su, sv = np.full(length, u0), np.arange(v0, v0 + length)
        u, v = np.concatenate([u, su]), np.concatenate([v, sv])
    if len(keep_clear_px) and len(u):
        d = np.hypot(u[:, None] - keep_clear_px[None, :, 0], v[:, None] - keep_clear_px[None, :, 1])
        clear = d.min(axis=1) > clearance_px
        if streak and not clear[n:].all():
            clear[n:] = False  # a streak is drawn whole or not at all
        u, v = u[clear], v[clear]
    image[v, u] = np.maximum(image[v, u], rng.uniform(120, 255, len(u)))


def render_field(
    size_px: tuple[int, int],
    spots: Spots,
    rng: np.random.Generator,
    params: RenderParams,
) -> NDArray[np.uint8]:
    """Render one 8-bit field: spots, optical blur, noise pixels/streaks, background, noise.

    Noise pixels and streaks are added after the blur: they come from the sensor and the
    video link, not through the lens.
    """
    w, h = size_px
    image = np.zeros((h, w))
    draw_spots(image, spots)
    if params.blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), params.blur_px)
    add_noise_pixels(image, rng, params, spots.centre_px)
    image += params.background
    if params.noise_sigma > 0:
        image += rng.normal(0.0, params.noise_sigma, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def sphere_spots(
    camera: SynthCamera,
    xyz_mm: NDArray[np.float64],
    radius_mm: float,
    peak: float | NDArray[np.float64],
    bloom_px: float,
) -> Spots:
    """Spots of spheres of ``radius_mm`` centred at ``xyz_mm`` (n, 3) as ``camera`` sees them.

    The angular radius of a sphere at distance ``d`` is ``asin(r / d)``; its outline on the
    normalised image plane is mapped through the lens Jacobian and the principal distances.
    """
    xyz_mm = np.asarray(xyz_mm, dtype=float).reshape(-1, 3)
    pc = camera.to_camera(xyz_mm)
    xn = pc[:, :2] / pc[:, 2:3]
    dist = np.linalg.norm(pc, axis=1)
    rho = np.tan(np.arcsin(np.clip(radius_mm / dist, 0, 1)))
    jac = camera.lens.jacobian(xn)  # (n, 2, 2)
    focal = np.diag([camera.K[0, 0], camera.K[1, 1]])
    shape = (focal @ jac) * rho[:, None, None] + bloom_px * np.eye(2)
    centre = camera.normalised_to_px(camera.lens.distort(xn))
    return Spots(centre, shape, np.broadcast_to(np.asarray(peak, float), len(xyz_mm)).copy())


def concat_spots(*parts: Spots) -> Spots:
    """One :class:`Spots` holding all the given spots, in order."""
    return Spots(
        np.concatenate([p.centre_px.reshape(-1, 2) for p in parts]),
        np.concatenate([p.shape.reshape(-1, 2, 2) for p in parts]),
        np.concatenate([p.peak.reshape(-1) for p in parts]),
    )


def isolated(spots: Spots, margin_px: float = 2.5) -> NDArray[np.bool_]:
    """True for spots whose margin-grown bounding box overlaps no other spot's.

    The margin covers the blur and the anti-aliased rim, so an isolated spot's light does
    not mix with any other's.
    """
    n = len(spots.centre_px)
    if n < 2:
        return np.ones(n, dtype=bool)
    r = spots.radii_px + margin_px
    d = np.abs(spots.centre_px[:, None, :] - spots.centre_px[None, :, :])
    reach = r[:, None, :] + r[None, :, :]
    touching = np.all(d < reach, axis=2)
    np.fill_diagonal(touching, False)
    return ~touching.any(axis=1)
