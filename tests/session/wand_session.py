"""Add a wand trial (as centroid files) and an axes object (as images) to a synthetic session.

Centroid files are written from the session's true cameras (``truth/cameras.json``):
every visible wand marker's distorted image plus Gaussian noise, and the LED rings of
the facing cameras as stationary ghosts. Rendering 600 wand images per camera takes a
minute; these files take a fraction of a second, which keeps session tests fast.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import tomli_w

from kisscal.camera import Camera
from kisscal.io.config import load_toml
from kisscal.io.files import write_table
from kisscal.synth.render import RenderParams
from kisscal.synth.scene import visibility
from kisscal.synth.wand import AXES_POINTS_MM, WAND_MARKERS_MM, render_axes, wand_trial
from tests.synth.truth_cameras import camera_from_truth


def truth_rig(root: Path) -> tuple[Camera, ...]:
    doc = json.loads((root / "truth" / "cameras.json").read_text())
    return tuple(camera_from_truth(c) for c in doc["cameras"])


def add_wand_trial(
    root: Path,
    fields: int = 300,
    markers_mm: tuple[float, ...] = WAND_MARKERS_MM,
    stated_mm: tuple[float, ...] | None = None,
    noise_px: float = 0.05,
    seed: int = 3,
    cameras_at_once: int | None = None,
) -> None:
    """Write ``wand/<camera>.csv`` and add trial ``wand01`` and ``[wand]`` to session.toml.

    ``stated_mm`` is what session.toml says (default: the true ``markers_mm``);
    ``cameras_at_once=1`` shows the wand to one camera per field only.
    """
    rig = truth_rig(root)
    motion = wand_trial(seed, fields, 50.0, markers_mm)
    rng = np.random.default_rng([seed, 77])
    for ci, cam in enumerate(rig):
        vis = visibility(cam, motion)
        if cameras_at_once == 1:
            vis &= (np.arange(fields) % len(rig) == ci)[:, None]
        f, m = np.nonzero(vis)
        uv = cam.project(motion.xyz_mm[f, m]) + rng.normal(0, noise_px, (len(f), 2))
        others = np.array([c.centre_mm for c in rig if c.id != cam.id])
        leds = cam.project(others[cam.depth_mm(others) > 0])
        leds = leds[cam.in_image(leds, 3.0)]
        lf = np.repeat(np.arange(fields), len(leds))
        luv = np.tile(leds, (fields, 1))
        field = np.r_[f, lf]
        order = np.argsort(field, kind="stable")
        xy = np.concatenate([uv, luv])[order]
        write_table(
            root / "wand" / f"{cam.id}.csv",
            {"field": field[order], "x_px": xy[:, 0], "y_px": xy[:, 1]},
        )
    data = load_toml(root / "session.toml")
    data["trials"] = [t for t in data.get("trials", []) if t["name"] != "wand01"]
    data["trials"].append({"name": "wand01", "centroids": "wand/{camera}.csv"})
    data["wand"] = {"trial": "wand01", "markers_mm": list(stated_mm or markers_mm)}
    (root / "session.toml").write_text(tomli_w.dumps(data))


def add_axes(root: Path, hide_in: str | None = None, wand_only: bool = True) -> None:
    """Render ``axes/<camera>/`` and add ``[axes]``; ``hide_in`` blacks out one marker in
    that camera; ``wand_only`` also drops ``[grid]`` and ``[rods]``."""
    rig = truth_rig(root)
    axes = np.asarray(AXES_POINTS_MM, dtype=float)
    for ci, cam in enumerate(rig):
        frames, truth = render_axes(rig, ci, axes, RenderParams(), 5, 2)
        folder = root / "axes" / cam.id
        folder.mkdir(parents=True, exist_ok=True)
        for k, image in enumerate(frames):
            if cam.id == hide_in:
                u, v = truth["u_px"][1], truth["v_px"][1]
                cv2.ellipse(image, (round(u), round(v)), (12, 7), 0, 0, 360, 0, -1)
            cv2.imwrite(str(folder / f"{k:06d}.png"), image)
    data = load_toml(root / "session.toml")
    data["axes"] = {"images": "axes/{camera}/*.png", "points_mm": axes.tolist()}
    if wand_only:
        data.pop("grid", None)
        data.pop("rods", None)
    (root / "session.toml").write_text(tomli_w.dumps(data))
