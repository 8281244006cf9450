"""Synthetic known-target calibration: dot plates photographed under uneven light.

Labs that own a calibration object (a frame, a stepped dot plate) photograph it with
every camera and click a few of its points. This module makes such a set-up with truth,
as docs/synthetic.md ("Calibration objects beyond the rods") describes:
:func:`target_points` (the plate, upright in the lab's XZ plane), :func:`target_rig`
(its cameras: 1280 x 1024, square pixels, barrel lenses of 4 to 12 px at the corners),
:func:`render_target` (a photograph) and :func:`seed_points` (the clicked points).

Example
-------
>>> xyz, surface = target_points("stepped")
>>> xyz.shape, len(np.unique(xyz[:, 1]))
((204, 3), 4)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal.camera import Camera
from kisscal.synth.cameras import brown_lens, look_at
from kisscal.synth.render import Spots, draw_spots, pixel_truth

TargetKind = Literal["planar", "stepped"]
#: Radius of the target's dots (mm).
DOT_RADIUS_MM = 7.0
_SIZE_PX = (1280, 1024)


def target_points(kind: TargetKind) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The target's dot centres (n, 3) in lab mm and its surfaces as rectangles (m, 4, 3).

    The plate faces -Y (towards the cameras); the stepped plate's bands step back in +Y.
    """
    if kind == "planar":
        x, z = np.meshgrid(np.arange(-8, 9) * 50.0, 200.0 + np.arange(13) * 50.0)
        xyz = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
        surfaces = np.array([[[-440, 0, 160], [440, 0, 160], [440, 0, 840], [-440, 0, 840]]])
        return xyz, surfaces.astype(float)
    if kind != "stepped":
        raise ValueError(f"target kind must be 'planar' or 'stepped', not {kind!r}")
    pts, surfaces = [], []
    for step in range(4):  # bands of three rows, each higher band 80 mm further back
        depth = 80.0 * step
        x, z = np.meshgrid(np.arange(-8, 9) * 50.0, 200.0 + 200.0 * step + np.arange(3) * 50.0)
        pts.append(np.column_stack([x.ravel(), np.full(x.size, depth), z.ravel()]))
        z0, z1 = 160.0 + 200.0 * step, 340.0 + 200.0 * step
        surfaces.append([[-440, depth, z0], [440, depth, z0], [440, depth, z1], [-440, depth, z1]])
    return np.concatenate(pts), np.asarray(surfaces, dtype=float)


def target_rig(seed: int, n_cameras: int = 3) -> tuple[Camera, ...]:
    """Cameras 1.6 to 2 m in front of the target, spread over +-40 degrees."""
    rng = np.random.default_rng([seed, 8080])
    w, h = _SIZE_PX
    aim = np.array([0.0, 100.0, 500.0])
    cams = []
    for i, angle in enumerate(np.linspace(-40.0, 40.0, n_cameras)):
        a = np.radians(angle + rng.uniform(-5, 5))
        dist = rng.uniform(1600.0, 2000.0)
        centre = (
            aim + dist * np.array([np.sin(a), -np.cos(a), 0.0]) + [0, 0, rng.uniform(-200, 100)]
        )
        R = look_at(centre, aim + rng.uniform(-40, 40, 3), roll_deg=rng.uniform(-2, 2))
        f = rng.uniform(1400.0, 1700.0)
        K = np.array(
            [
                [f, 0, (w - 1) / 2 + rng.normal(0, 8)],
                [0, f, (h - 1) / 2 + rng.normal(0, 8)],
                [0, 0, 1],
            ]
        )
        corner = np.hypot(w / 2, h / 2) / f
        k1 = -rng.uniform(4.0, 12.0) / (np.hypot(w / 2, h / 2) * corner**2)
        lens = brown_lens(k1=k1, k2=rng.uniform(-0.2, 0.2) * abs(k1), p1=rng.uniform(-2e-4, 2e-4))
        cams.append(Camera(K, R, -R @ centre, lens, f"cam{i + 1}", (w, h)))
    return tuple(cams)


def dot_spots(camera: Camera, xyz_mm: NDArray[np.float64], step_mm: float = 0.5) -> Spots:
    """Image ellipses of flat round dots facing -Y: centre and local Jacobian of the view."""
    centre = camera.project(xyz_mm)
    ex = (camera.project(xyz_mm + [step_mm, 0, 0]) - centre) / step_mm
    ez = (camera.project(xyz_mm + [0, 0, step_mm]) - centre) / step_mm
    shape = np.stack([ex, ez], axis=-1) * DOT_RADIUS_MM
    return Spots(centre, shape, np.ones(len(xyz_mm)))


def visible_dots(camera: Camera, xyz_mm: NDArray[np.float64], margin_px: float = 8.0):
    """Dots inside the image (with a margin) and facing the camera."""
    inside = camera.in_image(camera.project(xyz_mm), margin_px)
    facing = (camera.centre_mm[1] - xyz_mm[:, 1]) < 0  # the camera is on the -Y side
    return inside & facing


def render_target(
    camera: Camera,
    xyz_mm: NDArray[np.float64],
    surfaces_mm: NDArray[np.float64],
    rng: np.random.Generator,
) -> NDArray[np.uint8]:
    """A photograph of the target: light plate, dark dots, uneven light, blur and noise
    (2 DN read noise)."""
    w, h = camera.size_px
    v, u = np.mgrid[0:h, 0:w].astype(float)
    lamp = rng.uniform([0.2 * w, 0.2 * h], [0.8 * w, 0.8 * h])
    light = 0.3 + 0.7 * np.exp(-((u - lamp[0]) ** 2 + (v - lamp[1]) ** 2) / (2 * (0.45 * w) ** 2))
    r2 = ((u - w / 2) ** 2 + (v - h / 2) ** 2) / (w * w / 4 + h * h / 4)
    light *= 1.0 - 0.35 * r2
    plate = np.zeros((h, w), dtype=np.uint8)
    for rect in surfaces_mm:
        edge = np.concatenate([np.linspace(rect[k], rect[(k + 1) % 4], 40) for k in range(4)])
        cv2.fillPoly(plate, [np.round(camera.project(edge)).astype(np.int32)], 1)
    image = np.where(plate > 0, 205.0, 45.0 + 15.0 * u / w)
    cover = np.zeros((h, w))
    seen = visible_dots(camera, xyz_mm, margin_px=-20.0)
    draw_spots(cover, dot_spots(camera, xyz_mm[seen]))
    image = (image * (1.0 - cover) + 35.0 * cover) * light
    image = cv2.GaussianBlur(image, (0, 0), 0.8)
    image += rng.normal(0.0, 2.0, image.shape) + rng.normal(0.0, 0.02, image.shape) * image
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def seed_points(
    camera: Camera,
    xyz_mm: NDArray[np.float64],
    rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Six clicked points: visible dots spread in 3D (farthest-point order), clicked
    with 0.5 px of error. Returns ``(uv_px (6, 2), xyz_mm (6, 3))``."""
    seen = np.flatnonzero(visible_dots(camera, xyz_mm, margin_px=40.0))
    pts = xyz_mm[seen]
    chosen = [int(np.argmax(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(pts - pts[chosen[0]], axis=1)
    while len(chosen) < 6:
        chosen.append(int(np.argmax(dist)))
        dist = np.minimum(dist, np.linalg.norm(pts - pts[chosen[-1]], axis=1))
    picked = pts[chosen]
    uv = camera.project(picked) + rng.normal(0.0, 0.5, (6, 2))
    return uv, picked


def truth_table(camera: Camera, xyz_mm: NDArray[np.float64]) -> dict[str, Sequence]:
    """Every dot's true image position (distorted and ideal) and whether it is visible."""
    return {
        "index": np.arange(len(xyz_mm)),
        **pixel_truth(camera.project(xyz_mm), camera.project_ideal(xyz_mm)),
        "visible": visible_dots(camera, xyz_mm).astype(int),
    }
