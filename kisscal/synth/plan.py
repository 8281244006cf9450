"""A whole synthetic session in memory: rig, rods, grid, trials, config and truth tables.

:func:`plan_session` decides everything a seed determines; the ``render_*`` functions
produce the images of one camera (grid, rods, or one trial) with their truth, so that
:mod:`kisscal.session.synth_session` can write cameras in parallel.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from kisscal.camera import Camera
from kisscal.errors import InputError
from kisscal.synth.cameras import PIXEL_ASPECT, VOLUME_MM, kiss_rig, ring_rig
from kisscal.synth.motion import (
    Motion,
    standing_template,
    stick_trial,
    throw_trial,
    walking_trial,
)
from kisscal.synth.render import (
    Glow,
    RenderParams,
    Spots,
    concat_spots,
    glow_map,
    pixel_truth,
    record,
    render_scene,
    sphere_spots,
)
from kisscal.synth.replay import inside_volume, slim_capsules
from kisscal.synth.scene import (
    FieldTruth,
    GridView,
    Rod,
    grid_view,
    image_rng,
    led_spots,
    render_markers,
    rod_conflicts,
    rod_set,
    visibility,
)
from kisscal.synth.wand import AXES_POINTS_MM, WAND_TRIAL, wand_trial

Range = tuple[float, float]
Volume = tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class RigSpec:
    """The geometry of one rig, as :mod:`kisscal.synth.presets` draws it for a seed.

    Attributes
    ----------
    preset : str
        The preset it was drawn from.
    layout, pixel_aspect, volume_mm, clearance_mm, height_mm, ring_start_deg
        As in :class:`~kisscal.synth.presets.RigPreset`.
    corner_distortion_px, marker_diameter_px, grid_fill, throw_s
        As in :class:`~kisscal.synth.presets.RigPreset`.
    size_px : (int, int)
        Image width and height.
    marker_size_quantile : float
        Where in the feasible range of marker radii this rig's radius lies (0 to 1).
    bit_depth : int
        Bits per pixel of the images (also in the render parameters).
    """

    preset: str = "kiss"
    layout: Literal["kiss", "ring"] = "kiss"
    size_px: tuple[int, int] = (752, 291)
    pixel_aspect: float = 1.0 / PIXEL_ASPECT
    volume_mm: Volume = VOLUME_MM
    clearance_mm: Range = (0.0, 0.0)
    height_mm: Range = (0.0, 0.0)
    ring_start_deg: Range | None = None
    corner_distortion_px: Range = (6.0, 9.0)
    marker_diameter_px: Range | None = None
    marker_size_quantile: float = 0.5
    bit_depth: int = 8
    grid_fill: float = 0.88
    throw_s: float = 0.9

    @property
    def inside_volume(self) -> bool:
        """Trials kept inside the volume (all but the KISS rig, which stays as it was)."""
        return self.layout != "kiss"


@dataclass(frozen=True)
class SynthOptions:
    """What to synthesise. Every default is the KISS-like preset.

    Attributes
    ----------
    seed : int
        The same seed gives byte-identical sessions.
    fields : int
        Fields of the model gait trial ``walk01``.
    n_cameras : int
        2 to 16 cameras.
    n_markers : int
        13 or 15 gait markers.
    rate_hz : float
        Field rate.
    grid_frames, rod_frames : int
        Frames recorded per camera of the grid and of the rods.
    stick_fields : int
        Fields of the stick trial (seed 003: 4 s).
    render : RenderParams
        Image appearance (blur, noise, LED rings ...); the marker radius of rigs with a
        marker size band is chosen by :func:`plan_session`.
    rig : RigSpec
        Cameras and volume (:func:`kisscal.synth.presets.synth_options` draws one).
    wand_fields : int
        Fields of a wand trial ``wand01`` with an L-frame for the lab axes
        (:mod:`kisscal.synth.wand`); 0: none.
    wand_only : bool
        Leave ``[grid]`` and ``[rods]`` out of ``session.toml``: calibrate from the wand
        and the L-frame alone.
    replay_in_view : bool
        Cut the replayed recording (``walk5``) to its longest run of fields inside the
        control volume, as the rigs other than KISS always do: the KISS rig sees the middle
        2.4 m of the recorded 6.7 m walk, so the whole replay is covered in only part of
        its fields (the demo cuts it; the KISS preset keeps the whole walk by default).
    trials : tuple of str, optional
        Write only these of the trials (``walk01``, ``stick``, ``throw``, ``walk5``,
        ``wand01``); each comes out as it does in the whole session. None: all of them.
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
    rig: RigSpec = field(default_factory=RigSpec)
    wand_fields: int = 0
    wand_only: bool = False
    replay_in_view: bool = False
    trials: tuple[str, ...] | None = None


class _Memo(dict):
    """Scenes and glow of a plan's latest camera; pickled empty (to no other process)."""

    def __reduce__(self) -> tuple:
        return _Memo, ()


@dataclass(frozen=True)
class SynthPlan:
    """Everything a seed determines, before any image is rendered.

    ``render`` is ``options.render`` with the rig's marker radius; ``rod_conflicts`` counts
    rod-marker images that touch an LED ring or another rod (0 but on crowded rigs).
    ``memo`` keeps the latest camera's scenes and glow (:func:`_per_camera`);
    ``trial_codes`` each trial's place among all the seed's trials (its images' noise).
    """

    options: SynthOptions
    rig: tuple[Camera, ...]
    rods: tuple[Rod, ...]
    trials: dict[str, Motion]
    marker_names: tuple[str, ...]
    template_mm: NDArray[np.float64]
    segments: tuple[tuple[str, str], ...]
    render: RenderParams = field(default_factory=RenderParams)
    rod_conflicts: int = 0
    axes_mm: NDArray[np.float64] | None = None
    trial_codes: dict[str, int] = field(default_factory=dict)
    memo: _Memo = field(default_factory=_Memo, init=False, repr=False, compare=False)


def plan_session(options: SynthOptions, replay: Motion | None = None) -> SynthPlan:
    """Decide the rig, rods and trials of a synthetic session.

    ``replay`` is an extra recorded trial (the real walking5.c3d moved into the volume,
    at ``options.rate_hz``) rendered as trial ``walk5``; a rig that keeps its trials
    inside the volume cuts it to the fields inside (at most ``options.fields``) and slims
    its capsules so that no marker hides behind its own (:func:`slim_capsules`; the KISS
    rig keeps the replay as it always was).
    """
    spec = options.rig
    rig = build_rig(options)
    render = options.render
    if spec.marker_diameter_px is not None:
        radius = marker_radius_mm(rig, spec, render.bloom_px)
        render = replace(render, marker_radius_mm=radius)
    trials = _trials(options, replay)
    gait = trials["walk01"]
    # an image's noise is drawn from its trial's place among all of them: a trial
    # written alone comes out as it does beside the others
    codes = {name: k for k, name in enumerate(trials)}
    if options.trials is not None:
        unknown = sorted(set(options.trials) - set(trials))
        if unknown:
            raise InputError(
                f"no trial {', '.join(unknown)} to synthesise; there are {', '.join(trials)}"
            )
        trials = {name: m for name, m in trials.items() if name in options.trials}
    rods, conflicts = _hang_rods(options, rig, render)
    return SynthPlan(
        options=options,
        rig=rig,
        rods=rods,
        trials=trials,
        trial_codes=codes,
        marker_names=gait.names,
        template_mm=standing_template(gait.names),
        segments=gait.segments,
        render=render,
        rod_conflicts=conflicts,
        axes_mm=np.asarray(AXES_POINTS_MM, dtype=float) if options.wand_fields else None,
    )


def build_rig(options: SynthOptions) -> tuple[Camera, ...]:
    """The cameras of ``options.rig`` for ``options.seed``."""
    spec = options.rig
    if spec.layout == "kiss":
        return kiss_rig(options.seed, options.n_cameras, spec.corner_distortion_px)
    return ring_rig(
        options.seed,
        options.n_cameras,
        spec.size_px,
        spec.volume_mm,
        spec.clearance_mm,
        spec.height_mm,
        spec.corner_distortion_px,
        pixel_aspect=spec.pixel_aspect,
        start_deg=spec.ring_start_deg,
    )


def marker_radius_mm(rig: tuple[Camera, ...], spec: RigSpec, bloom_px: float) -> float:
    """The marker radius that puts every marker image in the volume in ``spec``'s band.

    A sphere of radius ``r`` at distance ``d`` images ``2 (f r / d + bloom)`` pixels across
    (through the lens); over a 9^3 lattice of the volume in every camera, the
    radii that keep all images in the band form a range, and ``marker_size_quantile``
    picks one. An empty range (a band the geometry cannot meet) gives its middle.
    """
    if spec.marker_diameter_px is None:
        raise InputError("marker_radius_mm: the rig spec gives no marker_diameter_px band")
    lo, hi = (np.asarray(c, dtype=float) for c in spec.volume_mm)
    axes = [np.linspace(lo[k], hi[k], 9) for k in range(3)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    per_mm = np.concatenate([sphere_spots(c, points, 1.0, 1.0, 0.0).radii_px for c in rig])
    small, large = spec.marker_diameter_px
    r_min = (small / 2 - bloom_px) / per_mm.min()
    r_max = (large / 2 - bloom_px) / per_mm.max()
    if r_min > r_max:
        return float(0.5 * (r_min + r_max))
    return float(r_min + spec.marker_size_quantile * (r_max - r_min))


def _trials(options: SynthOptions, replay: Motion | None) -> dict[str, Motion]:
    """walk01, stick, throw (and walk5) for the rig's volume and field rate."""
    spec, seed, rate = options.rig, options.seed, options.rate_hz
    if not spec.inside_volume:
        trials = {
            "walk01": walking_trial(seed, options.fields, rate, options.n_markers),
            "stick": stick_trial(seed, options.stick_fields, rate),
            "throw": throw_trial(seed, rate),
        }
        if replay is not None and options.replay_in_view:
            replay = slim_capsules(inside_volume(replay, spec.volume_mm, options.fields))
        if replay is not None:
            trials["walk5"] = replay
        return _with_wand(trials, options)
    lo, hi = spec.volume_mm
    # the feet reach about 650 mm ahead of and behind the pelvis
    path_mm = (hi[0] - lo[0]) - 2 * 650.0
    trials = {
        "walk01": walking_trial(seed, options.fields, rate, options.n_markers, path_mm),
        "stick": stick_trial(seed, options.stick_fields, rate, spec.volume_mm),
        "throw": throw_trial(seed, rate, spec.volume_mm, spec.throw_s),
    }
    if replay is not None:
        trials["walk5"] = slim_capsules(inside_volume(replay, spec.volume_mm, options.fields))
    return _with_wand(trials, options)


def _with_wand(trials: dict[str, Motion], options: SynthOptions) -> dict[str, Motion]:
    """The trials, with the wand trial when ``options.wand_fields`` asks for one."""
    if options.wand_fields:
        trials[WAND_TRIAL] = wand_trial(
            options.seed, options.wand_fields, options.rate_hz, volume_mm=options.rig.volume_mm
        )
    return trials


def _hang_rods(
    options: SynthOptions, rig: tuple[Camera, ...], render: RenderParams
) -> tuple[tuple[Rod, ...], int]:
    """Rods near the volume's vertical edges, re-hung until every camera sees them clear.

    The KISS rig of up to six cameras checks only the LED rings (as it always did); other
    rigs also keep the rods apart from each other in every image. When no placement is
    clear (crowded rigs), the one with the fewest conflicts is kept; returns the rods and
    their conflicts (:func:`~kisscal.synth.scene.rod_conflicts`).
    """
    spec = options.rig
    if spec.layout == "kiss":
        place: dict = {}
        gap = 0.0 if options.n_cameras <= 6 else 4.0
    else:
        lo, hi = spec.volume_mm
        top = min(1900.0, hi[2] - 100.0)
        corners = ((hi[0] - lo[0]) / 2 - 50.0, (hi[1] - lo[1]) / 2 - 50.0)
        place, gap = {"top_mm": top, "corners_xy_mm": corners}, 4.0
    best, fewest = None, None
    for attempt in range(50):
        rods = rod_set(options.seed, attempt=attempt, **place)
        conflicts = rod_conflicts(rig, rods, render, line_gap_px=gap)
        if fewest is None or conflicts < fewest:
            best, fewest = rods, conflicts
        if conflicts == 0:
            break
    return best, fewest


# ------------------------------------------------------------------------- rendering


def _per_camera(plan: SynthPlan, key: str, cam_index: int, make: Callable[[], Any]) -> Any:
    """``make()`` once per plan and camera: a camera's trials, rods, grid and detection
    truth share its glow and scenes (recomputing them took a third of a rig check). Only
    the latest camera's are kept (a 2048 x 2048 camera's take 32 MB each); their arrays are
    read-only, as every caller shares them."""
    if plan.memo.get("camera") != cam_index:
        plan.memo.clear()
        plan.memo["camera"] = cam_index
    if key not in plan.memo:
        value = make()
        for a in value if isinstance(value, tuple) else (value,):
            if isinstance(a, np.ndarray):
                a.flags.writeable = False
        plan.memo[key] = value
    return plan.memo[key]


def camera_glow(
    plan: SynthPlan, cam_index: int, plate_px: tuple[float, float, float, float] | None = None
) -> NDArray[np.float64] | None:
    """One camera's background light (``None`` for a flat background); ``plate_px`` adds the
    lit grid plate of its grid images."""
    glow = plan.render.glow
    if glow is None:
        return None
    size = plan.rig[cam_index].size_px
    rng = np.random.default_rng([plan.options.seed, 7007, cam_index])
    light = _per_camera(plan, "glow", cam_index, lambda: glow_map(size, glow, rng))
    if plate_px is None:
        return light
    plate_rng = np.random.default_rng([plan.options.seed, 7008, cam_index])
    plate_only = Glow((0.0, 0.0), (0.0, 0.0), (0, 0), (0.0, 0.0), (0.1, 0.1), glow.plate_dn)
    return light + glow_map(size, plate_only, plate_rng, plate_px)


def grid_scene(
    plan: SynthPlan, cam_index: int
) -> tuple[GridView, NDArray[np.float64], NDArray[np.float64] | None]:
    """One camera's view of the grid: dots, their noise-free light, the background."""
    return _per_camera(plan, "grid", cam_index, lambda: _grid_scene(plan, cam_index))


def _grid_scene(
    plan: SynthPlan, cam_index: int
) -> tuple[GridView, NDArray[np.float64], NDArray[np.float64] | None]:
    cam = plan.rig[cam_index]
    view = grid_view(
        cam,
        plan.options.seed,
        fill=plan.options.rig.grid_fill,
        dot_radius_px=plan.render.grid_dot_radius_px,
    )
    scene = render_scene(cam.size_px, view.spots, plan.render)
    plate = None
    if plan.render.glow is not None:
        # the plate reaches a dot spacing beyond the outer dots
        spacing = np.median(np.linalg.norm(np.diff(view.uv_px, axis=0), axis=1))
        lo, hi = view.uv_px.min(axis=0) - spacing, view.uv_px.max(axis=0) + spacing
        plate = (lo[0], lo[1], hi[0], hi[1])
    return view, scene, camera_glow(plan, cam_index, plate)


def render_grid(plan: SynthPlan, cam_index: int) -> tuple[list[NDArray], dict]:
    """Grid frames of one camera and the truth of its 300 dots."""
    view, scene, background = grid_scene(plan, cam_index)
    frames = [
        record(
            scene,
            image_rng(plan.options.seed, "grid", cam_index, k),
            plan.render,
            view.spots.centre_px,
            background,
        )
        for k in range(plan.options.grid_frames)
    ]
    r, c = np.divmod(np.arange(view.rows * view.cols), view.cols)
    truth = {"row": r, "col": c, **pixel_truth(view.uv_px, view.uv_ideal_px)}
    return frames, truth


def rod_scene(plan: SynthPlan, cam_index: int) -> tuple[Spots, Spots, NDArray[np.float64]]:
    """One camera's view of the rods: marker spots, LED-ring spots, their noise-free light."""
    return _per_camera(plan, "rods", cam_index, lambda: _rod_scene(plan, cam_index))


def _rod_scene(plan: SynthPlan, cam_index: int) -> tuple[Spots, Spots, NDArray[np.float64]]:
    cam = plan.rig[cam_index]
    params = plan.render
    points = np.concatenate([r.points_mm for r in plan.rods])
    spots = sphere_spots(cam, points, params.marker_radius_mm, params.marker_peak, params.bloom_px)
    leds = led_spots(cam, plan.rig, params)
    return spots, leds, render_scene(cam.size_px, concat_spots(spots, leds), params)


def render_rods(plan: SynthPlan, cam_index: int) -> tuple[list[NDArray], dict, dict]:
    """Rod frames of one camera, the truth of its 24 markers and of the LED rings it sees."""
    cam = plan.rig[cam_index]
    spots, leds, scene = rod_scene(plan, cam_index)
    background = camera_glow(plan, cam_index)
    keep_clear = concat_spots(spots, leds).centre_px
    frames = [
        record(
            scene,
            image_rng(plan.options.seed, "rods", cam_index, k),
            plan.render,
            keep_clear,
            background,
        )
        for k in range(plan.options.rod_frames)
    ]
    points = np.concatenate([r.points_mm for r in plan.rods])
    uv_ideal = cam.project_ideal(points)
    truth = {
        "rod": np.repeat([r.name for r in plan.rods], 6),
        "index": np.tile(np.arange(1, 7), len(plan.rods)),
        "x_mm": points[:, 0],
        "y_mm": points[:, 1],
        "z_mm": points[:, 2],
        **pixel_truth(spots.centre_px, uv_ideal),
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
) -> Iterator[tuple[int, NDArray, FieldTruth]]:
    """Yield ``(field, image, truth)`` for every field of ``trial`` in one camera."""
    cam = plan.rig[cam_index]
    motion = plan.trials[trial]
    params = plan.render
    vis = visibility(cam, motion)
    leds = led_spots(cam, plan.rig, params)
    background = camera_glow(plan, cam_index)
    trial_code = plan.trial_codes[trial]
    for f in range(motion.n_fields):
        rng = image_rng(plan.options.seed, "trial", cam_index, f, trial_code)
        image, truth = render_markers(cam, motion.xyz_mm[f], vis[f], leds, rng, params, background)
        yield f, image, truth
