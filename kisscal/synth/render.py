"""Rendering of infrared fields: marker spots, LED rings, background glow, sensor noise.

A retro-reflective sphere images as a bright, nearly uniform elliptical spot (the pixels
are not square). Each spot is drawn with an anti-aliased edge: the grey value is the
fraction of the pixel the ellipse covers, estimated from the signed distance of the
pixel centre to the ellipse boundary. The ellipse is the sphere's outline mapped through
the local Jacobian of the lens distortion, so its centre is exactly the distorted
projection of the sphere's centre: that is the truth centroid.

A field is rendered in two steps: :func:`render_scene` draws and blurs the light of the
spots (grey levels above the background, on the 8-bit scale), :func:`record` adds what
the camera adds (noise pixels and streaks, background light, read and shot noise) and
quantises to the camera's bit depth. The noise-free scene gives the spots' true sizes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal._shared import as_points
from kisscal.camera import Camera, distort, distortion_jacobian, normalised_to_px


@dataclass(frozen=True)
class Glow:
    """Background light: the room seen through the infrared filter (8-bit grey levels).

    Each camera has its own, the same in all its images: a floor, a linear ramp in a random
    direction, and soft patches (lamps, windows, a lit floor); in grid images the grid's
    plate is lit as well.

    Attributes
    ----------
    level_dn : (float, float)
        Range of the floor.
    gradient_dn : (float, float)
        Range of the ramp's rise across the image.
    patches : (int, int)
        Least and most number of patches.
    patch_dn : (float, float)
        Range of a patch's peak.
    patch_size : (float, float)
        Range of a patch's sigma, as a fraction of the image diagonal.
    plate_dn : (float, float)
        Range of the grid plate's brightness above the room.
    """

    level_dn: tuple[float, float] = (2.0, 5.0)
    gradient_dn: tuple[float, float] = (0.0, 3.0)
    patches: tuple[int, int] = (0, 2)
    patch_dn: tuple[float, float] = (2.0, 8.0)
    patch_size: tuple[float, float] = (0.1, 0.3)
    plate_dn: tuple[float, float] = (2.0, 6.0)


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
    led_flare_px : float
        Added to an LED ring's radius on top of ``bloom_px`` (direct light blooms more).
    marker_radius_mm : float
        Radius of the marker spheres.
    grid_dot_radius_px : float
        Radius of a grid dot's image (the grid is seen square on).
    electrons_per_dn : float
        Photo-electrons per grey level: shot noise of variance ``signal / electrons_per_dn``
        (0: none).
    bit_depth : int
        8 (uint8 images) or 10 to 16 (uint16 images holding values 0 .. 2^bit_depth - 1);
        every grey level here is on the 8-bit scale and scaled by ``(2^bit_depth - 1) / 255``.
    glow : Glow or None
        Background light; ``None``: the flat ``background``.
    """

    background: float = 6.0
    noise_sigma: float = 0.0
    marker_peak: float = 230.0
    bloom_px: float = 0.5
    blur_px: float = 0.6
    noise_pixels: float = 3.0
    streak_probability: float = 0.3
    led_radius_mm: float = 60.0
    led_flare_px: float = 1.5
    marker_radius_mm: float = 12.5
    grid_dot_radius_px: float = 2.6
    electrons_per_dn: float = 0.0
    bit_depth: int = 8
    glow: Glow | None = None

    @property
    def dn_scale(self) -> float:
        """Grey levels of the recorded image per grey level of the 8-bit scale."""
        return (2**self.bit_depth - 1) / 255.0


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
    Vectorised over the spots of a field, a patch of one size for spots of about one
    size (a camera's LED ring among markers a third of its size would make every patch
    nine times larger), the patches combined with ``np.maximum.at``.
    """
    if len(spots.centre_px) == 0:
        return
    h, w = image.shape
    half = np.ceil(spots.radii_px).astype(int) + 2  # (n, 2): along u and v
    size_class = np.ceil(np.log2(half.max(axis=1))).astype(int)
    for c in np.unique(size_class):
        pick = np.flatnonzero(size_class == c)
        part = Spots(spots.centre_px[pick], spots.shape[pick], spots.peak[pick])
        rows, cols, value = _spot_patches(part, half[pick].max(axis=0), supersample)
        ok = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h) & (value > 0)
        np.maximum.at(image, (rows[ok], cols[ok]), value[ok])


def _spot_patches(
    spots: Spots, half: NDArray[np.int64], supersample: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """Rows, columns and grey values (n, Pv, Pu each) of patches reaching ``half`` (u, v)
    pixels either side of each spot's centre pixel: two beyond its half-extent along each
    axis (a pixel farther out than its half-extent and a sub-pixel gets nothing: the
    distance to the outline along the ray from the centre is never less than the distance
    along an axis)."""
    n = len(spots.centre_px)
    cu = np.rint(spots.centre_px[:, 0]).astype(int)
    cv = np.rint(spots.centre_px[:, 1]).astype(int)
    px = cu[:, None, None] + np.arange(-half[0], half[0] + 1)[None, None, :]  # (n, 1, Pu)
    py = cv[:, None, None] + np.arange(-half[1], half[1] + 1)[None, :, None]  # (n, Pv, 1)
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    inv = np.linalg.inv(spots.shape)
    coverage = np.zeros((n, py.shape[1], px.shape[2]))
    work = np.empty_like(coverage)  # one temporary for all passes (same numbers, in place)
    for sy in sub:  # supersample**2 passes, each vectorised over all spots and pixels
        for sx in sub:
            du = px + sx - spots.centre_px[:, 0, None, None]
            dv = py + sy - spots.centre_px[:, 1, None, None]
            a = inv[:, 0, 0, None, None] * du + inv[:, 0, 1, None, None] * dv
            b = inv[:, 1, 0, None, None] * du + inv[:, 1, 1, None, None] * dv
            np.multiply(a, a, out=a)
            np.multiply(b, b, out=b)
            np.add(a, b, out=a)
            np.sqrt(a, out=a)  # rho: 1 on the outline
            np.maximum(a, 1e-9, out=a)
            np.divide(1.0, a, out=a)
            np.subtract(1.0, a, out=a)
            np.multiply(np.hypot(du, dv, out=work), a, out=work)  # px outside the outline
            np.multiply(work, supersample, out=work)
            np.subtract(0.5, work, out=work)
            np.maximum(work, 0.0, out=work)
            np.minimum(work, 1.0, out=work)
            coverage += work
    value = coverage / supersample**2 * spots.peak[:, None, None]
    rows, cols = np.broadcast_arrays(py, px)
    return rows, cols, value


def add_noise_pixels(
    image: NDArray[np.float64],
    rng: np.random.Generator,
    params: RenderParams,
    keep_clear_px: NDArray[np.float64],
) -> None:
    """Add isolated bright pixels and, sometimes, a one-pixel-wide streak (in place).

    Noise is kept 8 px away from the points in ``keep_clear_px`` (the spots), so
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
        clear = d.min(axis=1) > 8.0
        if streak and not clear[n:].all():
            clear[n:] = False  # a streak is drawn whole or not at all
        u, v = u[clear], v[clear]
    image[v, u] = np.maximum(image[v, u], rng.uniform(120, 255, len(u)))


def render_scene(size_px: tuple[int, int], spots: Spots, params: RenderParams) -> NDArray:
    """The light of ``spots`` on the sensor: drawn, then blurred by the optics (float64)."""
    w, h = size_px
    image = np.zeros((h, w))
    draw_spots(image, spots)
    if params.blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), params.blur_px)
    return image


def record(
    scene: NDArray[np.float64],
    rng: np.random.Generator,
    params: RenderParams,
    keep_clear_px: NDArray[np.float64],
    background: NDArray[np.float64] | None = None,
) -> NDArray[np.uint8] | NDArray[np.uint16]:
    """What the camera records of ``scene``: noise pixels, background light, noise, quantised.

    Noise pixels and streaks are added after the blur: they come from the sensor and the
    video link, not through the lens. ``background`` (a glow map) replaces the flat
    ``params.background``. Shot noise follows the light, background included.
    """
    image = scene.copy()
    add_noise_pixels(image, rng, params, keep_clear_px)
    image += params.background if background is None else background
    # In place, one spare image: a 2048 x 2048 frame is 32 MB a copy, and every
    # temporary of it costs as much as the arithmetic (same numbers, same order).
    if params.electrons_per_dn > 0:
        sd = np.maximum(image, 0.0)
        sd /= params.electrons_per_dn
        sd += params.noise_sigma**2
        np.sqrt(sd, out=sd)
        sd *= rng.standard_normal(image.shape)
        image += sd
    elif params.noise_sigma > 0:
        image += rng.normal(0.0, params.noise_sigma, image.shape)
    eight = params.bit_depth == 8
    if not eight:
        image *= params.dn_scale
    np.rint(image, out=image)
    np.clip(image, 0, 2**params.bit_depth - 1, out=image)
    return image.astype(np.uint8 if eight else np.uint16)


def glow_map(
    size_px: tuple[int, int],
    glow: Glow,
    rng: np.random.Generator,
    plate_px: tuple[float, float, float, float] | None = None,
) -> NDArray[np.float64]:
    """One camera's background light (8-bit scale): floor, ramp, patches, lit grid plate.

    ``plate_px`` is the grid plate's (left, top, right, bottom) in pixels, for grid images.
    """
    w, h = size_px
    y, x = np.mgrid[0:h, 0:w].astype(float)
    diagonal = np.hypot(w, h)
    angle = rng.uniform(0, 2 * np.pi)
    along = ((x - w / 2) * np.cos(angle) + (y - h / 2) * np.sin(angle)) / diagonal + 0.5
    light = rng.uniform(*glow.level_dn) + rng.uniform(*glow.gradient_dn) * along
    for _ in range(int(rng.integers(glow.patches[0], glow.patches[1] + 1))):
        u, v = rng.uniform(0, w), rng.uniform(0, h)
        sigma = rng.uniform(*glow.patch_size) * diagonal
        peak = rng.uniform(*glow.patch_dn)
        light += peak * np.exp(-((x - u) ** 2 + (y - v) ** 2) / (2 * sigma**2))
    if plate_px is not None:
        plate = np.zeros((h, w))
        left, top, right, bottom = (round(c) for c in plate_px)
        plate[max(top, 0) : max(bottom, 0), max(left, 0) : max(right, 0)] = 1.0
        light += rng.uniform(*glow.plate_dn) * cv2.GaussianBlur(plate, (0, 0), 3.0)
    return light


@dataclass(frozen=True)
class SpotSizes:
    """Width, height (bounding box, px) and pixel count of spot images above a grey level.

    Measured on the noise-free scene; NaN for a spot not lit above the level at its centre
    or sharing its lit pixels with another spot.
    """

    width_px: NDArray[np.float64]
    height_px: NDArray[np.float64]
    pixels: NDArray[np.float64]


def spot_sizes(
    scene: NDArray[np.float64], spots: Spots, level: float, rim_px: float = 2.5
) -> SpotSizes:
    """:class:`SpotSizes` of ``spots`` in ``scene`` at grey level ``level``.

    Each spot is measured in a window reaching ``rim_px`` plus two pixels beyond its
    outline: a lit region that reaches the window's edge, or holds another spot's centre,
    is not the spot's alone (NaN).
    """
    n = len(spots.centre_px)
    out = np.full((3, n), np.nan)
    h, w = scene.shape
    reach = np.ceil(spots.radii_px + rim_px).astype(int) + 2
    centre = np.rint(spots.centre_px).astype(int)
    for i in range(n):  # a few dozen spots per image, each a small window
        (u, v), (rx, ry) = centre[i], reach[i]
        if u - rx < 0 or v - ry < 0 or u + rx >= w or v + ry >= h:
            continue  # cut by the image border
        window = scene[v - ry : v + ry + 1, u - rx : u + rx + 1] >= level
        _, labels, stats, _ = cv2.connectedComponentsWithStats(window.astype(np.uint8), 8)
        own = labels[ry, rx]
        if own == 0:
            continue
        x0, y0, bw, bh, area = stats[own]
        if x0 == 0 or y0 == 0 or x0 + bw == window.shape[1] or y0 + bh == window.shape[0]:
            continue
        others = np.delete(centre, i, axis=0) - [u - rx, v - ry]
        inside = np.all((others >= 0) & (others < window.shape[::-1]), axis=1)
        if np.any(labels[others[inside, 1], others[inside, 0]] == own):
            continue
        out[:, i] = (bw, bh, area)
    return SpotSizes(out[0], out[1], out[2])


def sphere_spots(
    camera: Camera,
    xyz_mm: NDArray[np.float64],
    radius_mm: float,
    peak: float | NDArray[np.float64],
    bloom_px: float,
) -> Spots:
    """Spots of spheres of ``radius_mm`` centred at ``xyz_mm`` (n, 3) as ``camera`` sees them.

    The angular radius of a sphere at distance ``d`` is ``asin(r / d)``; its outline on the
    normalised image plane is mapped through the lens Jacobian and the principal distances.
    """
    xyz_mm = as_points(xyz_mm, 3, "xyz_mm")
    pc = camera.to_camera(xyz_mm)
    xn = pc[:, :2] / pc[:, 2:3]
    dist = np.linalg.norm(pc, axis=1)
    rho = np.tan(np.arcsin(np.clip(radius_mm / dist, 0, 1)))
    jac = distortion_jacobian(camera.lens, xn)  # (n, 2, 2)
    focal = np.diag([camera.K[0, 0], camera.K[1, 1]])
    shape = (focal @ jac) * rho[:, None, None] + bloom_px * np.eye(2)
    centre = normalised_to_px(camera.K, distort(camera.lens, xn))
    return Spots(centre, shape, np.broadcast_to(np.asarray(peak, float), len(xyz_mm)).copy())


def pixel_truth(uv_px: NDArray, ideal_px: NDArray) -> dict[str, NDArray]:
    """Truth table columns of image positions: as imaged (``u_px``, ``v_px``) and through
    a lens without distortion (``u_ideal_px``, ``v_ideal_px``)."""
    return {
        "u_px": uv_px[:, 0],
        "v_px": uv_px[:, 1],
        "u_ideal_px": ideal_px[:, 0],
        "v_ideal_px": ideal_px[:, 1],
    }


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
