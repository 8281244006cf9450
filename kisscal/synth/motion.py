"""Marker motion for synthetic trials: a kinematic walker, the seeds' stick and thrown marker.

The walker is a sagittal-plane chain (pelvis, thighs, shanks, feet) driven by normative
hip, knee and ankle flexion curves over the gait cycle; its forward speed is the one at
which the stance foot does not slip. Markers follow the KISS set (Küçük 2005: pelvis,
thigh, knee, shank, ankle, heel and toe on both legs) with two anterior pelvis markers
for the 15-marker set. Knee and ankle markers sit on the joint axes, so the distances
knee-ankle, knee-shank, ankle-heel and so on are fixed: ``segments`` lists them.
Body segments are also returned as capsules, which block lines of sight (occlusion).
``walking_trial(..., model="grounded")`` is the walker of :mod:`kisscal.synth.walker`
instead, built from the feet up so that they roll on the floor without slipping; it
carries its true foot contacts and gait (:class:`kisscal.synth.walker.GaitTruth`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from kisscal.synth.body import PELVIS_HALF_LENGTH_MM, PELVIS_MARKERS, PELVIS_RADIUS_MM
from kisscal.synth.cameras import VOLUME_MM
from kisscal.synth.walker import GaitTruth, grounded_walk

#: Gravitational acceleration used for the thrown marker (Ankara, seed 003 section 5.1).
G_MM_S2 = 9806.0
#: Length of the validation stick between its two marker centres (seed 003 section 5.1).
STICK_LENGTH_MM = 502.5


@dataclass(frozen=True)
class Motion:
    """Marker trajectories of one trial, with the body capsules that occlude them.

    Attributes
    ----------
    names : tuple of str
        Marker names, one per column of ``xyz_mm``.
    xyz_mm : ndarray, shape (n_fields, n_markers, 3)
        Marker centres in lab millimetres (NaN where the marker does not exist).
    capsules_mm : ndarray, shape (n_fields, n_capsules, 2, 3)
        End points of the body capsules per field.
    capsule_radius_mm : ndarray, shape (n_capsules,)
    rate_hz : float
    segments : tuple of (str, str)
        Marker pairs whose distance does not change.
    truth : GaitTruth or None
        True foot contacts and gait of the grounded walker (None for other motions).
    """

    names: tuple[str, ...]
    xyz_mm: NDArray[np.float64]
    capsules_mm: NDArray[np.float64]
    capsule_radius_mm: NDArray[np.float64]
    rate_hz: float
    segments: tuple[tuple[str, str], ...] = ()
    truth: GaitTruth | None = None

    @property
    def n_fields(self) -> int:
        return self.xyz_mm.shape[0]


# Normative sagittal joint angles (degrees) at 0, 10, ..., 90 % of the gait cycle, heel
# strike at 0 %: hip flexion, knee flexion, ankle dorsiflexion. Periodic splines through
# these knots give smooth curves with the textbook shape.
_PHASE_KNOTS = np.linspace(0.0, 1.0, 11)
_HIP_DEG = np.array([30, 25, 16, 6, -4, -10, -4, 14, 27, 32, 30], dtype=float)
_KNEE_DEG = np.array([5, 17, 13, 6, 4, 14, 40, 62, 38, 10, 5], dtype=float)
_ANKLE_DEG = np.array([0, -6, 2, 8, 10, 2, -15, -6, 2, 2, 0], dtype=float)

# Body dimensions (mm) of the walker.
_THIGH_MM, _SHANK_MM = 430.0, 420.0
_HIP_HALF_WIDTH_MM = 85.0
#: Stature of this geometry (mm): the standing hip height, 930 mm, is 0.530 H (Winter 2009).
_REFERENCE_HEIGHT_MM = 1755.0
_STRIDE_SAMPLES = 400


def _leg_points(phase: NDArray[np.float64], side: float) -> dict[str, NDArray[np.float64]]:
    """Points of one leg at gait-cycle phases ``phase`` (see :func:`_leg_from_angles`)."""
    hip_c, knee_c, ankle_c = (
        CubicSpline(_PHASE_KNOTS, np.radians(k), bc_type="periodic")
        for k in (_HIP_DEG, _KNEE_DEG, _ANKLE_DEG)
    )
    return _leg_from_angles(hip_c(phase % 1.0), knee_c(phase % 1.0), ankle_c(phase % 1.0), side)


def _leg_from_angles(
    th: NDArray[np.float64], tk: NDArray[np.float64], ta: NDArray[np.float64], side: float
) -> dict[str, NDArray[np.float64]]:
    """Points of one leg in the pelvis frame (x forward, y left, z up), shape (n, 3) each.

    ``th, tk, ta`` are hip flexion, knee flexion and ankle dorsiflexion in radians;
    ``side`` is -1 for the right leg and +1 for the left.
    """
    n = len(th)
    lat = np.array([0.0, side, 0.0])
    hip = np.tile([0.0, side * _HIP_HALF_WIDTH_MM, 0.0], (n, 1))

    def along(angle: NDArray) -> NDArray:  # unit vector down a limb flexed forward by angle
        return np.stack([np.sin(angle), np.zeros(n), -np.cos(angle)], axis=1)

    thigh_dir = along(th)
    knee = hip + _THIGH_MM * thigh_dir
    shank_angle = th - tk
    ankle = knee + _SHANK_MM * along(shank_angle)
    foot_angle = shank_angle + ta
    fwd = np.stack([np.cos(foot_angle), np.zeros(n), np.sin(foot_angle)], axis=1)
    up = np.stack([-np.sin(foot_angle), np.zeros(n), np.cos(foot_angle)], axis=1)
    heel_end = ankle - 40 * fwd - 40 * up
    toe_end = ankle + 130 * fwd - 50 * up
    return {
        "hip": hip,
        "knee": knee,
        "ankle": ankle,
        "heel_end": heel_end,
        "toe_end": toe_end,
        "THI": hip + 0.55 * _THIGH_MM * thigh_dir + 95 * lat,
        "KNE": knee + 70 * lat,
        "TIB": knee + 0.5 * _SHANK_MM * along(shank_angle) + 70 * lat,
        "ANK": ankle + 60 * lat,
        "HEE": ankle - 85 * fwd - 30 * up,
        "TOE": ankle + 140 * fwd - 5 * up,
    }


_LEG_MARKERS = ("THI", "KNE", "TIB", "ANK", "HEE", "TOE")
#: Capsules: (name, radius mm); leg capsules per side.
_LEG_CAPSULES = (("thigh", 65.0), ("shank", 45.0), ("foot", 30.0))


def gait_marker_names(n_markers: int = 15) -> tuple[str, ...]:
    """The KISS marker set: 13 (sacrum + 6 per leg) or 15 (plus both ASIS)."""
    if n_markers not in (13, 15):
        raise ValueError(f"the gait marker set has 13 or 15 markers, not {n_markers}")
    pelvis = ["SACR"] if n_markers == 13 else ["SACR", "RASI", "LASI"]
    return tuple(pelvis + [s + m for s in "RL" for m in _LEG_MARKERS])


def gait_segments(names: tuple[str, ...]) -> tuple[tuple[str, str], ...]:
    """Marker pairs on one rigid segment of the walker (fixed distances)."""
    pairs = [("RASI", "LASI"), ("RASI", "SACR"), ("LASI", "SACR")]
    for s in "RL":
        pairs += [
            (f"{s}THI", f"{s}KNE"),
            (f"{s}KNE", f"{s}TIB"),
            (f"{s}KNE", f"{s}ANK"),
            (f"{s}TIB", f"{s}ANK"),
            (f"{s}ANK", f"{s}HEE"),
            (f"{s}ANK", f"{s}TOE"),
            (f"{s}HEE", f"{s}TOE"),
        ]
    return tuple((a, b) for a, b in pairs if a in names and b in names)


def _stride_geometry() -> float:
    """Stride length (mm) per unit cycle.

    The forward speed is the mean backward speed of the stance ankle relative to the
    pelvis over the stance phase (0-60 %): at that speed the stance foot does not slip.
    """
    phase = np.linspace(0.0, 1.0, _STRIDE_SAMPLES, endpoint=False)
    leg = _leg_points(phase, -1.0)
    stance = phase < 0.6
    dx = np.gradient(leg["ankle"][:, 0], phase)
    return -np.mean(dx[stance])


def _pelvis_height(phase: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pelvis height that puts the lower foot on the floor, smoothed to 6 harmonics."""
    grid = np.linspace(0.0, 1.0, _STRIDE_SAMPLES, endpoint=False)
    lowest = np.full(len(grid), np.inf)
    for side, offset in ((-1.0, 0.0), (1.0, 0.5)):
        leg = _leg_points(grid + offset, side)
        for key in ("heel_end", "toe_end"):
            lowest = np.minimum(lowest, leg[key][:, 2] - 30.0)
    height = -lowest
    spectrum = np.fft.rfft(height)
    spectrum[7:] = 0.0
    smooth = np.fft.irfft(spectrum, len(grid))
    return np.interp(phase % 1.0, grid, smooth, period=1.0)


def walking_trial(
    seed: int,
    n_fields: int,
    rate_hz: float = 50.0,
    n_markers: int = 15,
    path_mm: float = 3400.0,
    *,
    model: Literal["kinematic", "grounded"] = "kinematic",
    height_m: float | None = None,
    heading_deg: float | None = None,
    start_mm: tuple[float, float] | None = None,
    turn_deg: float = 0.0,
) -> Motion:
    """A subject walking along the lab X axis through the control volume.

    The walking speed is chosen so that the subject covers ``path_mm`` (the 2.4 m volume
    plus a margin) during the trial, between 0.5 and 1.3 m/s; the cadence follows from
    the stride length. Direction (+X or -X), lateral offset and starting phase vary with
    the seed. Markers outside the cameras' view are the renderer's business.

    ``model="grounded"`` is the walker of :mod:`kisscal.synth.walker`, whose feet roll on
    the floor without slipping; its :attr:`Motion.truth` holds the true foot contacts
    and gait. ``height_m`` scales the body (default 1.755 m, the default geometry);
    ``heading_deg`` sets the walking direction (degrees from +X towards +Y) and
    ``start_mm`` the pelvis' floor position at field 0 (default: the path is centred on
    the volume, off by a random lateral offset); ``turn_deg`` (grounded only) bends the
    path by that many degrees over the trial. Left at their defaults, the kinematic
    walker is the same as before these options existed.
    """
    rng = np.random.default_rng([seed, 2002])
    names = gait_marker_names(n_markers)
    t = np.arange(n_fields) / rate_hz
    speed = np.clip(path_mm / max(t[-1], 1e-9), 500.0, 1300.0)
    phase0 = rng.uniform(0, 1)
    heading = rng.choice([0.0, np.pi]) + rng.uniform(-0.05, 0.05)
    lateral = rng.uniform(-150, 150)
    if heading_deg is not None:
        heading = np.radians(heading_deg)
    k = 1.0 if height_m is None else height_m * 1000.0 / _REFERENCE_HEIGHT_MM
    if model == "grounded":
        return _grounded(names, t, rate_hz, speed, k, heading, start_mm, lateral, phase0, turn_deg)
    if model != "kinematic":
        raise ValueError(f"walker model must be 'kinematic' or 'grounded', not {model!r}")
    if turn_deg:
        raise ValueError("turn_deg needs model='grounded'")
    stride_mm = _stride_geometry()
    cycle_s = k * stride_mm / speed
    phase = t / cycle_s + phase0
    forward = speed * (t - t[-1] / 2) if start_mm is None else speed * t
    if start_mm is not None:
        lateral = 0.0

    yaw = np.radians(4.0) * np.sin(2 * np.pi * phase)
    sway = k * 15.0 * np.sin(2 * np.pi * phase)
    height = k * _pelvis_height(phase)
    origin_local = np.stack([forward, lateral + sway, height], axis=1)
    shift = np.zeros(3) if start_mm is None else np.array([*start_mm, 0.0])

    def to_lab(p_pelvis: NDArray) -> NDArray:
        """Pelvis-frame points (n, 3) -> lab, with the pelvis yaw and the walking heading."""
        p_pelvis = k * p_pelvis
        c, s = np.cos(yaw), np.sin(yaw)
        x = c * p_pelvis[:, 0] - s * p_pelvis[:, 1]
        y = s * p_pelvis[:, 0] + c * p_pelvis[:, 1]
        local = np.stack([x, y, p_pelvis[:, 2]], axis=1) + origin_local
        ch, sh = np.cos(heading), np.sin(heading)
        lab = np.stack(
            [ch * local[:, 0] - sh * local[:, 1], sh * local[:, 0] + ch * local[:, 1], local[:, 2]],
            axis=1,
        )
        return lab if start_mm is None else lab + shift

    legs = {"R": _leg_points(phase, -1.0), "L": _leg_points(phase + 0.5, 1.0)}
    markers = []
    for name in names:
        if name in PELVIS_MARKERS:
            markers.append(to_lab(np.tile(PELVIS_MARKERS[name], (n_fields, 1))))
        else:
            markers.append(to_lab(legs[name[0]][name[1:]]))
    capsules = [
        np.stack(
            [
                to_lab(np.tile([0.0, -PELVIS_HALF_LENGTH_MM, 40.0], (n_fields, 1))),
                to_lab(np.tile([0.0, PELVIS_HALF_LENGTH_MM, 40.0], (n_fields, 1))),
            ],
            axis=1,
        )
    ]
    radii = [k * PELVIS_RADIUS_MM]
    for side in "RL":
        leg = legs[side]
        ends = {
            "thigh": ("hip", "knee"),
            "shank": ("knee", "ankle"),
            "foot": ("heel_end", "toe_end"),
        }
        for cap, radius in _LEG_CAPSULES:
            a, b = ends[cap]
            capsules.append(np.stack([to_lab(leg[a]), to_lab(leg[b])], axis=1))
            radii.append(k * radius)
    return Motion(
        names=names,
        xyz_mm=np.stack(markers, axis=1),
        capsules_mm=np.stack(capsules, axis=1),
        capsule_radius_mm=np.asarray(radii),
        rate_hz=rate_hz,
        segments=gait_segments(names),
    )


def _grounded(
    names: tuple[str, ...],
    t: NDArray,
    rate_hz: float,
    speed: float,
    k: float,
    heading: float,
    start_mm: tuple[float, float] | None,
    lateral: float,
    phase0: float,
    turn_deg: float,
) -> Motion:
    """The walker of :mod:`kisscal.synth.walker` as a :class:`Motion` with its truth."""
    if start_mm is None:
        direction = np.array([np.cos(heading), np.sin(heading)])
        normal = np.array([-direction[1], direction[0]])
        start = lateral * normal - speed * t[-1] / 2 * direction
    else:
        start = np.asarray(start_mm, dtype=float)
    markers, capsules, radii, truth = grounded_walk(
        names,
        len(t),
        rate_hz,
        float(speed),
        k * _REFERENCE_HEIGHT_MM,
        float(heading),
        start,
        float(phase0),
        np.radians(turn_deg),
    )
    return Motion(
        names=names,
        xyz_mm=np.stack([markers[n] for n in names], axis=1),
        capsules_mm=capsules,
        capsule_radius_mm=radii,
        rate_hz=rate_hz,
        segments=gait_segments(names),
        truth=truth,
    )


def standing_template(names: tuple[str, ...]) -> NDArray[np.float64]:
    """Marker positions (mm) of the walker standing upright, feet flat, facing +X."""
    zero = np.zeros(1)
    legs = {
        "R": _leg_from_angles(zero, zero, zero, -1.0),
        "L": _leg_from_angles(zero, zero, zero, 1.0),
    }
    floor_offset = -min(legs["R"][k][0, 2] for k in ("heel_end", "toe_end")) + 30.0
    out = [
        PELVIS_MARKERS[name] if name in PELVIS_MARKERS else legs[name[0]][name[1:]][0]
        for name in names
    ]
    return np.asarray(out) + [0.0, 0.0, floor_offset]


def _volume_half_mid(volume_mm: tuple) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lo, hi = np.asarray(volume_mm[0], dtype=float), np.asarray(volume_mm[1], dtype=float)
    return (hi - lo) / 2, (hi + lo) / 2


def unit_direction(azimuth: NDArray, elevation: NDArray) -> NDArray[np.float64]:
    """Unit vectors (n, 3) at ``azimuth`` about Z from X and ``elevation`` above the XY plane."""
    ce = np.cos(elevation)
    return np.stack([ce * np.cos(azimuth), ce * np.sin(azimuth), np.sin(elevation)], axis=1)


def stick_trial(
    seed: int, n_fields: int = 200, rate_hz: float = 50.0, volume_mm: tuple = VOLUME_MM
) -> Motion:
    """Seed 003 section 5.1: a stick with two markers 502.5 mm apart moved through the volume.

    The stick's centre follows a Lissajous path that visits the whole control volume
    (``volume_mm``, (min, max) corners) while the stick turns through varying
    orientations, its ends staying inside; nothing occludes it.
    """
    rng = np.random.default_rng([seed, 3003])
    t = np.arange(n_fields) / rate_hz
    ph = rng.uniform(0, 2 * np.pi, 6)
    half, mid = _volume_half_mid(volume_mm)
    amplitude = (half[0] - 320.0, half[1] - 300.0, 0.3 * 2 * half[2])
    centre = np.stack(
        [
            mid[0] + amplitude[0] * np.sin(2 * np.pi * 0.25 * t + ph[0]),
            mid[1] + amplitude[1] * np.sin(2 * np.pi * 0.35 * t + ph[1]),
            mid[2] + amplitude[2] * np.sin(2 * np.pi * 0.3 * t + ph[2]),
        ],
        axis=1,
    )
    azimuth = 2 * np.pi * 0.3 * t + ph[3]
    elevation = 0.9 * np.sin(2 * np.pi * 0.4 * t + ph[4])
    direction = unit_direction(azimuth, elevation)
    half = 0.5 * STICK_LENGTH_MM * direction
    xyz = np.stack([centre - half, centre + half], axis=1)
    return Motion(
        names=("S1", "S2"),
        xyz_mm=xyz,
        capsules_mm=np.zeros((n_fields, 0, 2, 3)),
        capsule_radius_mm=np.zeros(0),
        rate_hz=rate_hz,
        segments=(("S1", "S2"),),
    )


def throw_trial(
    seed: int, rate_hz: float = 50.0, volume_mm: tuple = VOLUME_MM, duration_s: float = 0.9
) -> Motion:
    """Seed 003 section 5.1: a marker thrown across the volume (ballistic, g = 9.806 m/s^2).

    The marker flies from one end of the volume (``volume_mm``) to the other in
    ``duration_s``, rising about 0.8 m in 0.9 s (a shorter flight is a harder, flatter
    throw: the same arc scaled in time), and stays inside the volume.
    """
    rng = np.random.default_rng([seed, 4004])
    t = np.arange(round(duration_s * rate_hz) + 1) / rate_hz
    half, mid = _volume_half_mid(volume_mm)
    reach = half[0] - 100.0
    start = np.array([mid[0] - reach, rng.uniform(-300, 300), rng.uniform(500, 700)])
    sideways = rng.uniform(-200, 200)
    upwards = rng.uniform(3800, 4100) * (duration_s / 0.9)  # the same arc in duration_s
    velocity = np.array([2 * reach / duration_s, sideways, upwards])
    xyz = start + t[:, None] * velocity
    xyz[:, 2] -= 0.5 * G_MM_S2 * t**2
    n = len(t)
    return Motion(
        names=("BALL",),
        xyz_mm=xyz[:, None, :],
        capsules_mm=np.zeros((n, 0, 2, 3)),
        capsule_radius_mm=np.zeros(0),
        rate_hz=rate_hz,
        segments=(),
    )
