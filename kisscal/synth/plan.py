"""A whole synthetic session in memory: rig, rods, grid, trials, config and truth tables.

:func:`plan_session` decides everything a seed determines; the ``render_*`` functions
produce the images of one camera (grid, rods, or one trial) with their truth, so that
:mod:`kisscal.io.synthetic` can write cameras in parallel.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kisscal.synth.cameras import SynthCamera, kiss_rig
from kisscal.synth.motion import (
    MARKER_RADIUS_MM,
    Motion,
    standing_template,
    stick_trial,
    throw_trial,
    walking_trial,
)
from kisscal.synth.render import RenderParams, Spots, concat_spots, render_field, sphere_spots
from kisscal.synth.scene import (
    FieldTruth,
    Rod,
    grid_view,
    image_rng,
    led_spots,
    render_markers,
    rod_set,
    rods_clear_of_leds,
    visibility,
)
from kisscal.synth.wand import WAND_TRIAL, axes_points, wand_tables, wand_trial


@dataclass(frozen=True)
class SynthOptions:
    """What to synthesise. Every default is the KISS-like preset.

    Attributes
    ----------
    seed : int
        The same seed gives byte-identical sessions.
    fields : int
        Fields of the model gait trial ``walk01`` (50 Hz).
    n_cameras : int
        2 to 6 cameras.
    n_markers : int
        13 or 15 gait markers.
    rate_hz : float
        Field rate.
    grid_frames, rod_frames : int
        Frames recorded per camera of the grid and of the rods.
    stick_fields : int
        Fields of the stick trial (seed 003: 4 s).
    render : RenderParams
        Image appearance (blur, noise, LED rings ...).
    wand_fields : int
        Fields of a wand trial ``wand01`` with an L-frame for the lab axes
        (:mod:`kisscal.synth.wand`); 0: none.
    wand_only : bool
        Leave ``[grid]`` and ``[rods]`` out of ``session.toml``: calibrate from the wand
        and the L-frame alone.
    """

    seed: int = 1
    fields: int = 200
    n_cameras: int = 6
    n_markers: int = 15
    rate_hz: float = 50.0
    grid_frames: int = 4
    rod_frames: int = 3
    stick_fields: int = 200
    render: RenderParams = field(default_factory=RenderParams)
    wand_fields: int = 0
    wand_only: bool = False


@dataclass(frozen=True)
class SynthPlan:
    """Everything a seed determines, before any image is rendered."""

    options: SynthOptions
    rig: tuple[SynthCamera, ...]
    rods: tuple[Rod, ...]
    trials: dict[str, Motion]
    marker_names: tuple[str, ...]
    template_mm: NDArray[np.float64]
    segments: tuple[tuple[str, str], ...]
    axes_mm: NDArray[np.float64] | None = None


def plan_session(options: SynthOptions, replay: Motion | None = None) -> SynthPlan:
    """Decide the rig, rods and trials of a synthetic session.

    ``replay`` is an extra recorded trial (the real walking5.c3d moved into the volume)
    rendered as trial ``walk5``.
    """
    rig = kiss_rig(options.seed, options.n_cameras)
    gait = walking_trial(options.seed, options.fields, options.rate_hz, options.n_markers)
    trials = {
        "walk01": gait,
        "stick": stick_trial(options.seed, options.stick_fields, options.rate_hz),
        "throw": throw_trial(options.seed, options.rate_hz),
    }
    if replay is not None:
        trials["walk5"] = replay
    if options.wand_fields:
        trials[WAND_TRIAL] = wand_trial(options.seed, options.wand_fields, options.rate_hz)
    rods = rod_set(options.seed)
    for attempt in range(1, 50):  # re-hang the rods until no LED ring hides a marker
        if rods_clear_of_leds(rig, rods, options.render):
            break
        rods = rod_set(options.seed, attempt=attempt)
    return SynthPlan(
        options=options,
        rig=rig,
        rods=rods,
        trials=trials,
        marker_names=gait.names,
        template_mm=standing_template(gait.names),
        segments=gait.segments,
        axes_mm=axes_points() if options.wand_fields else None,
    )


def session_config(plan: SynthPlan, name: str) -> dict:
    """The ``session.toml`` content (DESIGN.md schema) of a synthetic session."""
    config = {
        "session": {"name": name, "rate_hz": plan.options.rate_hz},
        "cameras": [{"id": c.id, "size": list(c.size_px)} for c in plan.rig],
        "grid": {"rows": 15, "cols": 20, "images": "grid/{camera}/*.png"},
        "rods": {
            "images": "rods/{camera}/*.png",
            "rod": [{"name": r.name, "points_mm": r.points_mm.tolist()} for r in plan.rods],
        },
        "markers": {
            "names": list(plan.marker_names),
            "template_mm": np.round(plan.template_mm, 1).tolist(),
            "segments": [list(s) for s in plan.segments],
        },
        "trials": [{"name": t, "images": f"trials/{t}/{{camera}}/*.png"} for t in plan.trials],
    }
    if plan.axes_mm is not None:
        return wand_tables(config, plan.axes_mm, plan.options.wand_only)
    return config


# ------------------------------------------------------------------------- rendering


def render_grid(plan: SynthPlan, cam_index: int) -> tuple[list[NDArray[np.uint8]], dict]:
    """Grid frames of one camera and the truth of its 300 dots."""
    cam = plan.rig[cam_index]
    view = grid_view(cam, plan.options.seed)
    frames = [
        render_field(
            cam.size_px,
            view.spots,
            image_rng(plan.options.seed, "grid", cam_index, k),
            plan.options.render,
        )
        for k in range(plan.options.grid_frames)
    ]
    r, c = np.divmod(np.arange(view.rows * view.cols), view.cols)
    truth = {
        "row": r,
        "col": c,
        "u_px": view.uv_px[:, 0],
        "v_px": view.uv_px[:, 1],
        "u_ideal_px": view.uv_ideal_px[:, 0],
        "v_ideal_px": view.uv_ideal_px[:, 1],
    }
    return frames, truth


def render_rods(plan: SynthPlan, cam_index: int) -> tuple[list[NDArray[np.uint8]], dict, dict]:
    """Rod frames of one camera, the truth of its 24 markers and of the LED rings it sees."""
    cam = plan.rig[cam_index]
    params = plan.options.render
    points = np.concatenate([r.points_mm for r in plan.rods])
    spots = sphere_spots(cam, points, MARKER_RADIUS_MM, params.marker_peak, params.bloom_px)
    leds = led_spots(cam, plan.rig, params)
    everything = concat_spots(spots, leds)
    frames = [
        render_field(
            cam.size_px, everything, image_rng(plan.options.seed, "rods", cam_index, k), params
        )
        for k in range(plan.options.rod_frames)
    ]
    uv_ideal = cam.project_ideal(points)
    truth = {
        "rod": np.repeat([r.name for r in plan.rods], 6),
        "index": np.tile(np.arange(1, 7), len(plan.rods)),
        "x_mm": points[:, 0],
        "y_mm": points[:, 1],
        "z_mm": points[:, 2],
        "u_px": spots.centre_px[:, 0],
        "v_px": spots.centre_px[:, 1],
        "u_ideal_px": uv_ideal[:, 0],
        "v_ideal_px": uv_ideal[:, 1],
    }
    return frames, truth, _led_truth(leds)


def _led_truth(leds: Spots) -> dict:
    r = leds.radii_px
    return {
        "u_px": leds.centre_px[:, 0],
        "v_px": leds.centre_px[:, 1],
        "rx_px": r[:, 0],
        "ry_px": r[:, 1],
    }


def trial_visibility(plan: SynthPlan, trial: str) -> NDArray[np.bool_]:
    """Visibility of every marker of ``trial`` in every camera, shape (F, M, C)."""
    motion = plan.trials[trial]
    return np.stack([visibility(cam, motion) for cam in plan.rig], axis=-1)


def render_trial(
    plan: SynthPlan, trial: str, cam_index: int
) -> Iterator[tuple[int, NDArray[np.uint8], FieldTruth]]:
    """Yield ``(field, image, truth)`` for every field of ``trial`` in one camera."""
    cam = plan.rig[cam_index]
    motion = plan.trials[trial]
    params = plan.options.render
    vis = visibility(cam, motion)
    leds = led_spots(cam, plan.rig, params)
    trial_code = list(plan.trials).index(trial)
    for f in range(motion.n_fields):
        rng = image_rng(plan.options.seed, "trial", cam_index, f, trial_code)
        image, truth = render_markers(cam, motion.xyz_mm[f], vis[f], leds, rng, params)
        yield f, image, truth
