"""Synthetic wand calibration: a wand waved through the volume and an L-frame on the floor.

A lab calibrating with a wand (Vicon, Qualisys, OptiTrack, easyWand, Argus) records a
trial of a person waving a rigid bar carrying two or more markers through the whole
control volume, turning it through every orientation, and a few frames of a static
object on the floor whose markers fix the lab frame (an "L-frame"). This module makes
both, as :class:`~kisscal.synth.motion.Motion` and marker arrays, so that
:mod:`kisscal.synth.plan` renders them like any trial.

The wand's centre sweeps the walkway along lab X while it is waved up and down and side
to side (incommensurate frequencies, so the path fills the volume and goes beyond it,
into the edges of every camera's view), and its direction
turns about the vertical while rocking in elevation; the person holding it is a capsule
beside the wand that hides it from some cameras now and then (partial views).

Example
-------
>>> motion = wand_trial(1, 50, 50.0, (0.0, 190.0, 500.0))
>>> motion.xyz_mm.shape
(50, 3, 3)
>>> lengths = np.linalg.norm(motion.xyz_mm[:, 2] - motion.xyz_mm[:, 0], axis=1)
>>> bool(np.allclose(lengths, 500.0))
True
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kisscal.camera import Camera
from kisscal.synth.cameras import VOLUME_MM
from kisscal.synth.motion import Motion, unit_direction
from kisscal.synth.render import (
    RenderParams,
    concat_spots,
    pixel_truth,
    record,
    render_scene,
    sphere_spots,
)
from kisscal.synth.scene import led_spots

#: The name of the wand trial in synthetic sessions.
WAND_TRIAL = "wand01"

#: The wand of the synthetic sessions: three markers, unequal gaps (the ends are told
#: apart), 500 mm from end to end.
WAND_MARKERS_MM: tuple[float, ...] = (0.0, 190.0, 500.0)
#: The L-frame on the floor (DESIGN.md's example): three markers along lab X, one along Y.
AXES_POINTS_MM: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.0, 0.0),
    (400.0, 0.0, 0.0),
    (0.0, 300.0, 0.0),
    (150.0, 0.0, 0.0),
)
_BODY_RADIUS_MM = 160.0
_BODY_HEIGHT_MM = 1500.0
_ARM_MM = 550.0

Volume = tuple[tuple[float, float, float], tuple[float, float, float]]


def wand_trial(
    seed: int,
    n_fields: int,
    rate_hz: float,
    markers_mm: Sequence[float] = WAND_MARKERS_MM,
    volume_mm: Volume = VOLUME_MM,
    reach: float = 0.3,
) -> Motion:
    """A wand waved through the whole control volume for ``n_fields`` fields.

    Parameters
    ----------
    seed : int
        Phases and speeds vary with the seed.
    n_fields : int
        Fields of the trial.
    rate_hz : float
        Field rate.
    markers_mm : sequence of float
        Marker positions along the wand's axis (mm), as in ``[wand] markers_mm``.
    volume_mm : ((x, y, z), (x, y, z))
        The control volume (min and max corners, lab mm).
    reach : float
        How far beyond the volume (fraction of its length and width) the wand is waved,
        so that it reaches the edges and corners of every camera's image, as a technician
        does; vertically it goes from a tenth of the volume's height to 15 % above it.

    Returns
    -------
    Motion
        Markers ``W1``, ``W2`` ... in ``markers_mm`` order; one capsule, the person
        holding the wand (it hides the wand from some cameras in some fields).
    """
    rng = np.random.default_rng([seed, 7007])
    lo, hi = np.asarray(volume_mm[0], float), np.asarray(volume_mm[1], float)
    size = hi - lo
    grow = np.array([reach, reach, 0.0]) * size
    inner_lo = lo - grow + [0.0, 0.0, 0.10 * size[2]]
    inner_hi = hi + grow + [0.0, 0.0, 0.15 * size[2]]
    t = np.arange(n_fields) / rate_hz
    duration = max(t[-1], 1e-9)
    ph = rng.uniform(0.0, 2.0 * np.pi, 6)
    # along the walkway: one and a half slow sweeps; across and up: faster waving
    sweep = 0.5 - 0.5 * np.cos(np.pi * 1.5 * t / duration + ph[0] * 0.1)
    across = 0.5 + 0.5 * np.sin(2 * np.pi * rng.uniform(0.45, 0.6) * t + ph[1])
    up = 0.5 + 0.5 * np.sin(2 * np.pi * rng.uniform(0.7, 0.9) * t + ph[2])
    unit = np.stack([sweep, across, up], axis=1)
    centre = inner_lo + unit * (inner_hi - inner_lo)
    azimuth = 2 * np.pi * rng.uniform(0.25, 0.35) * t + ph[3]
    elevation = 1.2 * np.sin(2 * np.pi * rng.uniform(0.35, 0.45) * t + ph[4])
    direction = unit_direction(azimuth, elevation)
    s = np.asarray(markers_mm, dtype=float)
    s = s - 0.5 * (s.min() + s.max())
    xyz = centre[:, None, :] + s[None, :, None] * direction[:, None, :]
    # the person stands at arm's length from the wand, on the side away from the centre
    side = np.where(centre[:, 1:2] > 0.5 * (lo[1] + hi[1]), 1.0, -1.0)
    body_xy = centre[:, :2] + side * np.array([0.0, _ARM_MM])
    capsules = np.stack(
        [
            np.column_stack([body_xy, np.zeros(n_fields)]),
            np.column_stack([body_xy, np.full(n_fields, _BODY_HEIGHT_MM)]),
        ],
        axis=1,
    )[:, None]
    return Motion(
        names=tuple(f"W{i + 1}" for i in range(len(s))),
        xyz_mm=xyz,
        capsules_mm=capsules,
        capsule_radius_mm=np.array([_BODY_RADIUS_MM]),
        rate_hz=rate_hz,
        segments=tuple((f"W{i + 1}", f"W{i + 2}") for i in range(len(s) - 1)),
    )


def wand_tables(config: dict, axes_mm: NDArray[np.float64], wand_only: bool) -> dict:
    """``session.toml`` content with ``[wand]`` and ``[axes]`` added (and, for a session
    calibrated from the wand alone, ``[grid]`` and ``[rods]`` left out)."""
    out = {k: v for k, v in config.items() if not (wand_only and k in ("grid", "rods"))}
    out["wand"] = {"trial": WAND_TRIAL, "markers_mm": list(WAND_MARKERS_MM)}
    out["axes"] = {"images": "axes/{camera}/*.png", "points_mm": np.round(axes_mm, 3).tolist()}
    return out


def render_axes(
    rig: Sequence[Camera],
    cam_index: int,
    axes_mm: NDArray[np.float64],
    params: RenderParams,
    seed: int,
    n_frames: int,
    background: NDArray[np.float64] | None = None,
) -> tuple[list[NDArray], dict[str, NDArray]]:
    """Frames of the L-frame as one camera sees it (with the other cameras' LED rings and
    the camera's ``background`` light), and the truth of its markers."""
    cam = rig[cam_index]
    spots = sphere_spots(cam, axes_mm, params.marker_radius_mm, params.marker_peak, params.bloom_px)
    leds = led_spots(cam, rig, params)
    scene = render_scene(cam.size_px, concat_spots(spots, leds), params)
    keep_clear = concat_spots(spots, leds).centre_px
    frames = [
        record(
            scene, np.random.default_rng([seed, 9009, cam_index, k]), params, keep_clear, background
        )
        for k in range(n_frames)
    ]
    ideal = cam.project_ideal(axes_mm)
    truth = {
        "index": np.arange(1, len(axes_mm) + 1),
        "x_mm": axes_mm[:, 0],
        "y_mm": axes_mm[:, 1],
        "z_mm": axes_mm[:, 2],
        **pixel_truth(spots.centre_px, ideal),
    }
    return frames, truth
