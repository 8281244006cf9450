"""3D points of the synthetic rig's gait trial, as reconstruction would deliver them.

True marker positions of ``kisscal.synth`` + noise, kept only in fields where at least two
cameras see the marker (the rig's geometric occlusion by body capsules and image bounds),
plus ghost points that live a few fields.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kisscal.synth.cameras import kiss_rig
from kisscal.synth.motion import standing_template, walking_trial
from kisscal.synth.scene import visibility
from tests.tracking._data import observe


@dataclass(frozen=True)
class RigTrial:
    names: tuple[str, ...]
    template_mm: np.ndarray
    segments: tuple[tuple[str, str], ...]
    truth: np.ndarray  # (n_markers, n_fields, 3)
    visible: np.ndarray  # (n_markers, n_fields): seen by >= 2 cameras
    field: np.ndarray
    xyz_mm: np.ndarray
    marker: np.ndarray  # -1 for ghosts
    rate_hz: float


def rig_gait(
    seed: int,
    n_fields: int = 300,
    noise_mm: float = 0.5,
    ghosts_per_field: float = 1.0,
    path_mm: float = 3400.0,
    min_cameras: int = 2,
) -> RigTrial:
    motion = walking_trial(seed, n_fields, path_mm=path_mm)
    rig = kiss_rig(seed, 6)
    seen = np.stack([visibility(cam, motion) for cam in rig], axis=-1).sum(axis=-1)
    truth = np.transpose(motion.xyz_mm, (1, 0, 2))
    visible = (seen >= min_cameras).T
    field, xyz, marker, visible = observe(
        truth, seed, noise_mm=noise_mm, ghosts_per_field=ghosts_per_field, visible=visible
    )
    return RigTrial(
        motion.names,
        standing_template(motion.names),
        motion.segments,
        truth,
        visible,
        field,
        xyz,
        marker,
        motion.rate_hz,
    )
