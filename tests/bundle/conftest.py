"""A wand waved through the KISS-like rig, as the cameras see it (no images): truth and blobs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from kisscal.bundle.wand import BlobTable
from kisscal.camera import Camera
from kisscal.synth.cameras import kiss_rig
from kisscal.synth.motion import Motion
from kisscal.synth.scene import visibility
from kisscal.synth.wand import WAND_MARKERS_MM, wand_trial


@dataclass(frozen=True)
class WandScene:
    rig: tuple[Camera, ...]
    motion: Motion
    markers_mm: tuple[float, ...]

    @property
    def ids(self) -> list[str]:
        return [c.id for c in self.rig]

    @property
    def sizes(self) -> list[tuple[int, int]]:
        return [c.size_px for c in self.rig]

    def blobs(self, ideal: bool, noise_px: float, seed: int = 0, leds: bool = True) -> BlobTable:
        """Every camera's blobs per field: wand markers (+ noise) and the LED rings."""
        rng = np.random.default_rng(seed)
        per_camera = []
        for cam in self.rig:
            vis = visibility(cam, self.motion)
            view = cam.project_ideal if ideal else cam.project
            others = np.array([c.centre_mm for c in self.rig if c.id != cam.id])
            led = view(others[cam.depth_mm(others) > 0]) if leds else np.zeros((0, 2))
            led = led[cam.in_image(led, 3.0)]
            frames = []
            for f in range(self.motion.n_fields):
                p = self.motion.xyz_mm[f][vis[f]]
                uv = view(p) + rng.normal(0.0, noise_px, (len(p), 2))
                frames.append(np.concatenate([uv, led]))
            per_camera.append(frames)
        return BlobTable.of(per_camera)


def scene(seed: int, fields: int, markers_mm=WAND_MARKERS_MM, n_cameras: int = 6) -> WandScene:
    rig = kiss_rig(seed, n_cameras)
    return WandScene(rig, wand_trial(seed, fields, 50.0, markers_mm), tuple(markers_mm))


@pytest.fixture(scope="session")
def wand_scene() -> WandScene:
    """Seed 2, 200 fields, the three-marker wand."""
    return scene(2, 200)
