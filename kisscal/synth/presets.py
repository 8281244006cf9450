"""Synthetic rigs of other labs: what ``kisscal synth --preset kiss|modern|lowcost`` draws.

A :class:`RigPreset` describes a kind of lab as ranges (image sizes, lens distortion,
marker and grid-dot sizes in pixels, sensor noise, background glow, bit depth, field rate);
:func:`synth_options` draws one rig of that kind from a seed. The three presets (``kiss``,
the KISS lab of Shafiq et al. 2001; ``modern``; ``lowcost``) and how marker sizes in
pixels follow from a drawn marker radius: docs/synthetic.md, "Presets".

Examples
--------
>>> options = synth_options("lowcost", seed=2)
>>> options.rig.size_px, options.n_cameras, options.rate_hz in (30.0, 50.0, 60.0)
((640, 480), 4, True)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from kisscal.errors import InputError
from kisscal.synth.cameras import MAX_CAMERAS, PIXEL_ASPECT, VOLUME_MM
from kisscal.synth.plan import RigSpec, SynthOptions
from kisscal.synth.render import Glow, RenderParams

Range = tuple[float, float]
Volume = tuple[tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class Sensor:
    """Noise and quantisation of a camera (grey levels on the 8-bit scale).

    Attributes
    ----------
    read_noise_dn : (float, float)
        Range of the read-noise sigma.
    electrons_per_dn : float
        Photo-electrons per grey level: shot noise has variance ``signal / electrons_per_dn``
        (0: no shot noise).
    noise_pixels : float
        Mean isolated bright pixels per image (hot pixels, transmission errors).
    streak_probability : float
        Chance that an image holds a one-pixel-wide streak (analogue video only).
    """

    read_noise_dn: Range = (0.0, 0.0)
    electrons_per_dn: float = 0.0
    noise_pixels: float = 3.0
    streak_probability: float = 0.3


@dataclass(frozen=True)
class RigPreset:
    """A kind of lab: the ranges one synthetic rig of that kind is drawn from.

    Attributes
    ----------
    name : str
    camera_models : tuple of (int, int, int)
        Width, height (px) and bit depth of the camera models a seed picks from (8 bits:
        8-bit PNG; 10, 12: 16-bit PNG holding values 0 .. 2^bits - 1, not shifted).
    pixel_aspect : float
        Height / width of a pixel, ``fx / fy``: the width / height of a round marker's
        image (1.94 for KISS video fields, 1 for square pixels).
    n_cameras : int
        Default number of cameras.
    layout : {"kiss", "ring"}
        ``kiss``: the KISS placement (:func:`kisscal.synth.cameras.kiss_rig`); ``ring``:
        cameras evenly spaced around the volume (:func:`kisscal.synth.cameras.ring_rig`).
    volume_mm : ((x, y, z), (x, y, z))
        The control volume every camera sees whole; the walkway runs along lab X.
    clearance_mm, height_mm : (float, float)
        Ring layout: distance of the cameras outside the volume's footprint, and height.
    ring_start_deg : (float, float) or None
        Ring layout: range of the first camera's azimuth from the walkway; ``None``:
        anywhere within one spacing.
    corner_distortion_px : (float, float)
        Lens distortion at the image corners.
    marker_diameter_px : (float, float) or None
        Band every marker image (width and height, bloom included) lies in; ``None``:
        25 mm markers whatever size they image at (the KISS lab's).
    grid_dot_diameter_px : (float, float)
        Range of the grid dots' diameter in pixels (across; the grid is seen square on).
    grid_fill : float
        Fraction of the image width the grid spans (less for wide-angle lenses, whose
        corners bend more than the grid's fourth-order lattice fit follows).
    blur_px : (float, float)
        Range of the optical blur sigma.
    bloom_px : float
        Blooming added to every bright spot's radius.
    marker_peak_dn : (float, float)
        Range of a marker plateau's grey level above the background.
    led_radius_mm : float
        Radius of the infrared strobe ring around each lens (facing cameras see it).
    led_flare_px : (float, float)
        Range of the flare added to a strobe ring's radius (direct light blooms more than
        light returned by a marker).
    rates_hz : tuple of float
        Field rates a seed picks from.
    fields : int
        Default fields of the gait trial (and of the stick trial; the replayed walk5 has
        at most as many).
    throw_s : float
        Flight time of the thrown marker (fast rigs: a shorter, harder throw keeps the
        trial's size in fields near the others').
    sensor : Sensor
    glow : Glow or None
        Background light; ``None``: a flat background of 6 grey levels.
    """

    name: str
    camera_models: tuple[tuple[int, int, int], ...]
    pixel_aspect: float
    n_cameras: int
    layout: Literal["kiss", "ring"]
    volume_mm: Volume
    clearance_mm: Range
    height_mm: Range
    corner_distortion_px: Range
    marker_diameter_px: Range | None
    grid_dot_diameter_px: Range
    grid_fill: float
    blur_px: Range
    bloom_px: float
    marker_peak_dn: Range
    led_radius_mm: float
    led_flare_px: Range
    rates_hz: tuple[float, ...]
    fields: int
    throw_s: float
    sensor: Sensor = field(default_factory=Sensor)
    glow: Glow | None = None
    ring_start_deg: Range | None = None


PRESETS: dict[str, RigPreset] = {
    "kiss": RigPreset(
        name="kiss",
        camera_models=((752, 291, 8),),
        pixel_aspect=1.0 / PIXEL_ASPECT,
        n_cameras=6,
        layout="kiss",
        volume_mm=VOLUME_MM,
        clearance_mm=(0.0, 0.0),
        height_mm=(0.0, 0.0),
        corner_distortion_px=(6.0, 9.0),
        marker_diameter_px=None,
        grid_dot_diameter_px=(5.2, 5.2),
        grid_fill=0.88,
        blur_px=(0.6, 0.6),
        bloom_px=0.5,
        marker_peak_dn=(230.0, 230.0),
        led_radius_mm=60.0,
        led_flare_px=(1.5, 1.5),
        rates_hz=(50.0,),
        fields=200,
        throw_s=0.9,
    ),
    "modern": RigPreset(
        name="modern",
        camera_models=(
            (1280, 1024, 8),
            (1280, 1024, 8),
            (1280, 1024, 8),
            (1280, 1024, 8),
            (1280, 1024, 10),
            (1280, 1024, 12),
            (2048, 2048, 8),
        ),
        pixel_aspect=1.0,
        n_cameras=8,
        layout="ring",
        volume_mm=((-2000.0, -1000.0, 0.0), (2000.0, 1000.0, 2000.0)),
        clearance_mm=(3000.0, 4000.0),
        height_mm=(2200.0, 3000.0),
        corner_distortion_px=(2.0, 6.0),
        marker_diameter_px=(6.0, 25.0),
        grid_dot_diameter_px=(20.0, 40.0),
        grid_fill=0.88,
        blur_px=(0.7, 1.1),
        bloom_px=0.5,
        marker_peak_dn=(200.0, 245.0),
        led_radius_mm=70.0,
        led_flare_px=(6.0, 10.0),
        rates_hz=(100.0, 120.0, 150.0),
        fields=50,
        throw_s=0.6,
        sensor=Sensor(
            read_noise_dn=(0.15, 0.35),
            electrons_per_dn=40.0,
            noise_pixels=2.0,
            streak_probability=0.0,
        ),
        glow=Glow(
            level_dn=(2.0, 5.0),
            gradient_dn=(0.0, 3.0),
            patches=(0, 2),
            patch_dn=(2.0, 8.0),
            patch_size=(0.1, 0.3),
            plate_dn=(2.0, 6.0),
        ),
    ),
    "lowcost": RigPreset(
        name="lowcost",
        camera_models=((640, 480, 8),),
        pixel_aspect=1.0,
        n_cameras=4,
        layout="ring",
        volume_mm=((-1500.0, -750.0, 0.0), (1500.0, 750.0, 1800.0)),
        clearance_mm=(1200.0, 1700.0),
        height_mm=(1700.0, 2200.0),
        corner_distortion_px=(10.0, 13.0),
        marker_diameter_px=(3.5, 12.0),
        grid_dot_diameter_px=(8.0, 14.0),
        grid_fill=0.82,
        blur_px=(0.8, 1.2),
        bloom_px=0.6,
        marker_peak_dn=(180.0, 230.0),
        led_radius_mm=40.0,
        led_flare_px=(7.0, 11.0),
        rates_hz=(30.0, 50.0, 60.0),
        fields=90,
        throw_s=0.9,
        sensor=Sensor(
            read_noise_dn=(2.5, 5.0), electrons_per_dn=8.0, noise_pixels=5.0, streak_probability=0.0
        ),
        glow=Glow(
            level_dn=(15.0, 30.0),
            gradient_dn=(5.0, 15.0),
            patches=(1, 2),
            patch_dn=(10.0, 30.0),
            patch_size=(0.1, 0.25),
            plate_dn=(10.0, 25.0),
        ),
        # two webcams at the ends of the walkway, two at its sides: every lateral marker
        # is seen by three of them
        ring_start_deg=(-10.0, 10.0),
    ),
}


def synth_options(
    preset: str = "kiss",
    seed: int = 1,
    *,
    fields: int | None = None,
    n_cameras: int | None = None,
    n_markers: int = 15,
    blur_px: float | None = None,
) -> SynthOptions:
    """The :class:`SynthOptions` of one rig of ``preset`` drawn from ``seed``.

    ``fields``, ``n_cameras`` and ``blur_px`` override the preset's (default fields, default
    cameras, blur drawn per seed). The ``kiss`` preset gives exactly the options of earlier
    versions (same seed, same bytes). Other presets make the stick trial as long as the
    gait trial.
    """
    if preset not in PRESETS:
        raise InputError(f"preset must be one of {', '.join(PRESETS)}, got {preset!r}")
    p = PRESETS[preset]
    n_cameras = p.n_cameras if n_cameras is None else n_cameras
    if not 2 <= n_cameras <= MAX_CAMERAS:
        raise InputError(f"cameras must be between 2 and {MAX_CAMERAS}, got {n_cameras}")
    fields = p.fields if fields is None else fields
    if p.layout == "kiss":
        render = RenderParams() if blur_px is None else RenderParams(blur_px=blur_px)
        return SynthOptions(
            seed=seed, fields=fields, n_cameras=n_cameras, n_markers=n_markers, render=render
        )
    rng = np.random.default_rng([seed, 9009, list(PRESETS).index(preset)])
    width, height, bits = p.camera_models[rng.integers(len(p.camera_models))]
    # the rig takes the preset's geometry as it is ("as in RigPreset", RigSpec says)
    same = {f.name: getattr(p, f.name) for f in dataclasses.fields(RigSpec) if hasattr(p, f.name)}
    spec = RigSpec(
        preset=preset,
        size_px=(width, height),
        marker_size_quantile=float(rng.uniform(0.15, 0.85)),
        bit_depth=bits,
        **same,
    )
    drawn_blur = float(rng.uniform(*p.blur_px))
    render = RenderParams(
        background=0.0,
        noise_sigma=float(rng.uniform(*p.sensor.read_noise_dn)),
        marker_peak=float(rng.uniform(*p.marker_peak_dn)),
        bloom_px=p.bloom_px,
        blur_px=drawn_blur if blur_px is None else blur_px,
        noise_pixels=p.sensor.noise_pixels,
        streak_probability=p.sensor.streak_probability,
        led_radius_mm=p.led_radius_mm,
        led_flare_px=float(rng.uniform(*p.led_flare_px)),
        grid_dot_radius_px=float(rng.uniform(*p.grid_dot_diameter_px)) / 2,
        electrons_per_dn=p.sensor.electrons_per_dn,
        bit_depth=spec.bit_depth,
        glow=p.glow,
    )
    rate = float(p.rates_hz[rng.integers(len(p.rates_hz))])
    return SynthOptions(
        seed=seed,
        fields=fields,
        n_cameras=n_cameras,
        n_markers=n_markers,
        rate_hz=rate,
        stick_fields=fields,
        render=render,
        rig=spec,
    )
