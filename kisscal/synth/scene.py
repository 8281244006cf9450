"""Scenes of a synthetic session: occlusion, calibration rods, the dot grid, trial fields.

Every image gets its own random stream, derived from the session seed and the image's
identity (kind, camera, frame), so the output is the same for a seed whatever order or
process renders it in.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kisscal.camera import Camera, distort, distortion_jacobian, normalised_to_px
from kisscal.synth.motion import Motion
from kisscal.synth.render import (
    RenderParams,
    Spots,
    SpotSizes,
    concat_spots,
    isolated,
    record,
    render_scene,
    sphere_spots,
    spot_sizes,
)

_KIND_CODES = {"grid": 1, "rods": 2, "trial": 3}

#: Grey levels, as fractions of the marker plateau above the background, at which the
#: true sizes of spot images are measured (truth/detection.json): at half the plateau
#: (the spot's outline) and at a tenth (nearly all the light of the spot, blurred rim
#: included).
SIZE_LEVELS: dict[str, float] = {"half": 0.5, "low": 0.1}


def image_rng(
    seed: int, kind: str, camera_index: int, frame: int, trial: int = 0
) -> np.random.Generator:
    """The random stream of one image."""
    return np.random.default_rng([seed, _KIND_CODES[kind], trial, camera_index, frame])


# --------------------------------------------------------------------------- occlusion


def segment_distance(p0: NDArray, p1: NDArray, q0: NDArray, q1: NDArray) -> NDArray[np.float64]:
    """Shortest distance between segments p0-p1 and q0-q1 (broadcast over leading axes)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.sum(d1 * d1, axis=-1)
    e = np.sum(d2 * d2, axis=-1)
    f = np.sum(d2 * r, axis=-1)
    c = np.sum(d1 * r, axis=-1)
    b = np.sum(d1 * d2, axis=-1)
    denom = a * e - b * b
    safe = np.where(denom > 1e-12 * a * e, denom, 1.0)
    s = np.where(denom > 1e-12 * a * e, np.clip((b * f - c * e) / safe, 0.0, 1.0), 0.0)
    e_safe = np.where(e > 0, e, 1.0)
    t = (b * s + f) / e_safe
    # clamp t and recompute s where t left [0, 1]
    t_clamped = np.clip(t, 0.0, 1.0)
    a_safe = np.where(a > 0, a, 1.0)
    s = np.where(t != t_clamped, np.clip((t_clamped * b - c) / a_safe, 0.0, 1.0), s)
    t = t_clamped
    closest_p = p0 + s[..., None] * d1
    closest_q = q0 + t[..., None] * d2
    return np.linalg.norm(closest_p - closest_q, axis=-1)


def visibility(camera: Camera, motion: Motion, margin_px: float = 3.0) -> NDArray[np.bool_]:
    """Which markers ``camera`` sees in each field, shape (n_fields, n_markers).

    A marker is seen when it exists, lies in front of the camera and inside the image
    (with a margin), and no body capsule crosses its line of sight.
    """
    xyz = motion.xyz_mm
    exists = np.all(np.isfinite(xyz), axis=-1)
    safe = np.where(exists[..., None], xyz, 0.0)
    seen = exists & (camera.depth_mm(safe) > 100.0)
    seen &= camera.in_image(camera.project(safe), margin_px)
    if motion.capsules_mm.shape[1]:
        c = camera.centre_mm
        caps = motion.capsules_mm[:, None, :, :, :]  # (F, 1, K, 2, 3)
        dist = segment_distance(
            np.broadcast_to(c, safe.shape)[:, :, None, :],
            safe[:, :, None, :],
            caps[..., 0, :],
            caps[..., 1, :],
        )
        seen &= ~np.any(dist < motion.capsule_radius_mm, axis=-1)
    return seen


def rim_px(params: RenderParams) -> float:
    """How far beyond its outline a spot's light reaches (blur and anti-aliased edge)."""
    return max(2.5, 3.0 * params.blur_px)


# ------------------------------------------------------------------------------- rods


@dataclass(frozen=True)
class Rod:
    """A hanging calibration rod: surveyed marker centres (6, 3), top to bottom, mm."""

    name: str
    points_mm: NDArray[np.float64]


# Relative gaps between consecutive markers, top to bottom. Every rod has its own
# pattern, none is the mirror image of another, and the cross-ratios of consecutive
# quadruples differ between rods: a rod is recognisable from any camera (seed 003, 3.3).
_ROD_GAPS = (
    (1.0, 1.6, 2.2, 1.3, 1.9),
    (2.1, 1.1, 1.5, 2.4, 1.0),
    (1.3, 2.4, 1.0, 1.8, 1.6),
    (1.7, 1.2, 2.6, 1.0, 1.4),
)
_ROD_CORNERS = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))


def rod_set(
    seed: int,
    top_mm: float = 1900.0,
    bottom_mm: float = 100.0,
    attempt: int = 0,
    corners_xy_mm: tuple[float, float] = (1150.0, 650.0),
) -> tuple[Rod, ...]:
    """The four rods R1..R4 hanging plumb near the vertical edges of the volume.

    The rods hang near ``(+-x, +-y)`` of ``corners_xy_mm``; ``attempt`` draws another
    small placement for the same seed (see :func:`rod_conflicts`).
    """
    rng = np.random.default_rng([seed, 5005, attempt] if attempt else [seed, 5005])
    sign = np.asarray(_ROD_CORNERS)
    rods = []
    for i, gaps in enumerate(_ROD_GAPS):
        g = np.asarray(gaps) / np.sum(gaps) * (top_mm - bottom_mm)
        z = top_mm - np.concatenate([[0.0], np.cumsum(g)])
        spread = 30.0 + 15.0 * attempt  # later attempts move the rods further
        xy = sign[i] * np.asarray(corners_xy_mm) + rng.uniform(-spread, spread, 2)
        pts = np.column_stack([np.full(6, xy[0]), np.full(6, xy[1]), z])
        rods.append(Rod(f"R{i + 1}", np.round(pts, 1)))
    return tuple(rods)


# ------------------------------------------------------------------------- LED rings


def led_spots(camera: Camera, rig: Sequence[Camera], params: RenderParams) -> Spots:
    """The infrared LED rings of the other cameras that ``camera`` faces: large bright spots."""
    others = np.array([c.centre_mm for c in rig if c.id != camera.id])
    if len(others) == 0:
        return Spots(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0))
    in_front = camera.depth_mm(others) > 0
    others = others[in_front]
    flare = params.bloom_px + params.led_flare_px
    spots = sphere_spots(camera, others, params.led_radius_mm, 255.0, flare)
    keep = camera.in_image(spots.centre_px, margin_px=-4.0)
    return Spots(spots.centre_px[keep], spots.shape[keep], spots.peak[keep])


def rod_conflicts(
    rig: Sequence[Camera],
    rods: Sequence[Rod],
    params: RenderParams,
    margin_px: float = 4.0,
    line_gap_px: float = 0.0,
) -> int:
    """How many rod-marker images touch an LED ring's, over all cameras (0: all clear).

    A technician hangs the rods so that every marker is seen on its own; a marker hidden
    behind a facing camera's LED ring could not be measured. With ``line_gap_px`` > 0 the
    rods must also be seen apart from each other and whole: marker images touching another
    rod's, markers within ``line_gap_px`` of another rod's image line (a ring of cameras
    looks along the volume's diagonals, where two rods line up), and marker images not
    ``margin_px`` inside the image count too.
    """
    points = np.concatenate([r.points_mm for r in rods])
    rod_of = np.repeat(np.arange(len(rods)), [len(r.points_mm) for r in rods])
    other = rod_of[:, None] != rod_of[None, :]
    conflicts = 0
    for cam in rig:
        leds = led_spots(cam, rig, params)
        markers = sphere_spots(
            cam, points, params.marker_radius_mm, params.marker_peak, params.bloom_px
        )
        if len(leds.centre_px):
            conflicts += int(_touching(markers, leds, margin_px).any(axis=1).sum())
        if line_gap_px > 0:
            conflicts += int((_touching(markers, markers, margin_px) & other).any(axis=1).sum())
            inside = cam.in_image(markers.centre_px - markers.radii_px, margin_px)
            inside &= cam.in_image(markers.centre_px + markers.radii_px, margin_px)
            conflicts += int((~inside).sum())
            gaps = _line_gaps_px(cam.project_ideal(points), rod_of)
            conflicts += int((gaps < line_gap_px).sum())
    return conflicts


def _touching(a: Spots, b: Spots, margin_px: float) -> NDArray[np.bool_]:
    """Which spots of ``a`` (rows) come within ``margin_px`` of which of ``b`` (columns)."""
    gap = np.abs(a.centre_px[:, None, :] - b.centre_px[None, :, :])
    reach = a.radii_px[:, None, :] + b.radii_px[None, :, :] + margin_px
    return np.all(gap < reach, axis=2)


def _line_gaps_px(uv: NDArray[np.float64], rod_of: NDArray[np.int64]) -> NDArray[np.float64]:
    """Distance (px) of every point to the image line of every other rod, flattened."""
    gaps = []
    for k in np.unique(rod_of):
        mine = uv[rod_of == k]
        direction = mine[-1] - mine[0]
        normal = np.array([-direction[1], direction[0]]) / np.linalg.norm(direction)
        gaps.append(np.abs((uv[rod_of != k] - mine[0]) @ normal))
    return np.concatenate(gaps)


# ------------------------------------------------------------------------------- grid


@dataclass(frozen=True)
class GridView:
    """One camera's view of the 15 x 20 dot grid: truth per dot (row-major order)."""

    rows: int
    cols: int
    uv_px: NDArray[np.float64]
    uv_ideal_px: NDArray[np.float64]
    spots: Spots


def grid_view(
    camera: Camera,
    seed: int,
    fill: float = 0.88,
    dot_radius_px: float = 2.6,
) -> GridView:
    """The dot grid (15 rows, 20 columns) at close range, nearly square to ``camera``,
    filling its view.

    The grid plane is tilted by up to 3 degrees about both image axes and turned by up
    to 2 degrees in its plane; dots are flat discs that image about ``2 dot_radius_px``
    pixels wide. Returns distorted and ideal pixel positions of every dot.
    """
    rng = np.random.default_rng([seed, 6006, int(camera.id.removeprefix("cam") or 0)])
    depth_mm = 1500.0
    rows, cols = 15, 20
    w = camera.size_px[0]
    half_x = min(camera.K[0, 2], w - 1 - camera.K[0, 2]) / camera.K[0, 0]
    spacing_mm = fill * 2 * half_x * depth_mm / (cols - 1)
    ax, ay = np.radians(rng.uniform(-3.0, 3.0, 2))
    az = np.radians(rng.uniform(-2.0, 2.0))
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    rot = rx @ ry @ rz
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    plane = np.column_stack(
        [
            (c.ravel() - (cols - 1) / 2) * spacing_mm,
            (r.ravel() - (rows - 1) / 2) * spacing_mm,
            np.zeros(r.size),
        ]
    )
    # Centre the grid on the principal point, with a small offset.
    offset = np.array(
        [rng.uniform(-0.01, 0.01) * depth_mm, rng.uniform(-0.01, 0.01) * depth_mm, depth_mm]
    )
    pc = plane @ rot.T + offset  # camera frame
    xn = pc[:, :2] / pc[:, 2:3]
    uv_ideal = normalised_to_px(camera.K, xn)
    uv = normalised_to_px(camera.K, distort(camera.lens, xn))
    # A flat dot of radius r on the (almost fronto-parallel) plane: angular radius r/z.
    radius_mm = dot_radius_px * depth_mm / camera.K[0, 0]
    rho = radius_mm / pc[:, 2]
    jac = distortion_jacobian(camera.lens, xn)
    focal = np.diag([camera.K[0, 0], camera.K[1, 1]])
    normal = rot[:, 2]
    # foreshortening of the disc by the tilt, along the plane's tilt direction
    shape = (
        (focal @ jac) @ np.diag([abs(normal[2]) ** 0.5, abs(normal[2]) ** 0.5]) * rho[:, None, None]
    )
    spots = Spots(uv, shape, np.full(len(uv), 220.0))
    return GridView(rows, cols, uv, uv_ideal, spots)


# ------------------------------------------------------------------------ trial fields


@dataclass(frozen=True)
class FieldTruth:
    """Truth of one rendered trial field in one camera (markers in motion order).

    ``sizes`` holds, per level of :data:`SIZE_LEVELS`, the markers' image sizes measured on
    the noise-free field (NaN for markers not seen or not alone).
    """

    visible: NDArray[np.bool_]
    uv_px: NDArray[np.float64]
    uv_ideal_px: NDArray[np.float64]
    radii_px: NDArray[np.float64]
    isolated: NDArray[np.bool_]
    sizes: dict[str, SpotSizes] = field(default_factory=dict)


def measure_sizes(
    scene: NDArray[np.float64], spots: Spots, params: RenderParams
) -> dict[str, SpotSizes]:
    """Sizes of ``spots`` in ``scene`` at every level of :data:`SIZE_LEVELS`."""
    return {
        name: spot_sizes(scene, spots, fraction * params.marker_peak, rim_px(params))
        for name, fraction in SIZE_LEVELS.items()
    }


def render_markers(
    camera: Camera,
    xyz_mm: NDArray[np.float64],
    visible: NDArray[np.bool_],
    leds: Spots,
    rng: np.random.Generator,
    params: RenderParams,
    background: NDArray[np.float64] | None = None,
) -> tuple[NDArray, FieldTruth]:
    """Render the visible markers ``xyz_mm`` (n, 3) plus LED rings into one field.

    ``background`` is the camera's glow map (:func:`kisscal.synth.render.glow_map`).
    """
    safe = np.where(np.isfinite(xyz_mm), xyz_mm, 0.0)
    spots = sphere_spots(camera, safe, params.marker_radius_mm, params.marker_peak, params.bloom_px)
    vis = Spots(spots.centre_px[visible], spots.shape[visible], spots.peak[visible])
    everything = concat_spots(vis, leds)
    scene = render_scene(camera.size_px, everything, params)
    image = record(scene, rng, params, everything.centre_px, background)
    rim = rim_px(params)
    iso = np.zeros(len(safe), dtype=bool)
    iso[visible] = isolated(everything, rim)[: int(visible.sum())]
    # a spot cut by the image border is not a clean, whole marker image either
    w, h = camera.size_px
    reach = spots.radii_px + rim
    inside = np.all(spots.centre_px - reach >= -0.5, axis=1)
    inside &= (spots.centre_px[:, 0] + reach[:, 0] <= w - 0.5) & (
        spots.centre_px[:, 1] + reach[:, 1] <= h - 0.5
    )
    iso &= inside
    sizes = measure_sizes(scene, vis, params)
    truth = FieldTruth(
        visible=visible,
        uv_px=spots.centre_px,
        uv_ideal_px=camera.project_ideal(safe),
        radii_px=spots.radii_px,
        isolated=iso,
        sizes={k: _scatter(v, visible) for k, v in sizes.items()},
    )
    return image, truth


def _scatter(sizes: SpotSizes, visible: NDArray[np.bool_]) -> SpotSizes:
    """Sizes of the visible spots spread back to all markers (NaN for the unseen)."""
    out = np.full((3, len(visible)), np.nan)
    out[:, visible] = [sizes.width_px, sizes.height_px, sizes.pixels]
    return SpotSizes(*out)
