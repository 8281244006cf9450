"""A walker whose feet meet the floor: true foot contacts for testing gait event detection.

The kinematic walker of :mod:`kisscal.synth.motion` drives the legs from joint-angle
curves and moves the pelvis at constant speed, so its feet slide and sink. This walker is
built from the feet up instead (:mod:`kisscal.synth.feet`: rolling heel, flat foot,
rolling forefoot and toes, swing). The pelvis moves at constant speed along a straight
or curved path, sways 15 mm toward the stance leg, yaws 4 degrees, and rides as high as
the legs (thigh 430, shank 420 mm) allow with the knees flexed at least 7 degrees. Knees
follow by two-link inverse kinematics in the plane of the sole and the hip, so every
marker pair of :func:`kisscal.synth.motion.gait_segments` stays rigid.

Timing follows normal walking: step length and cadence from the walk ratio (step length
over cadence, 0.0065 m min/step at 1.755 m stature, proportional to stature; Sekiya &
Nagasaki 1998), stance 66.5 % - 4.5 % per m/s of speed (60 % at 1.45 m/s; Perry 1992),
step width 5.5 % of stature. Every length scales with stature (1.755 m for the default
geometry: hip height 930 mm = 0.530 H, Winter 2009).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from kisscal.gait.table import GaitEvents
from kisscal.synth.body import PELVIS_HALF_LENGTH_MM, PELVIS_MARKERS, PELVIS_RADIUS_MM
from kisscal.synth.feet import SOLE_TILT, Body, GaitTiming, WalkPath, footprints, sole_pose

#: Stature (mm) of the default walker geometry.
REFERENCE_HEIGHT_MM = 1755.0
_WALK_RATIO = 6.5  # mm per (step/min) at the reference stature
_DENSE_S = 0.002  # time step of the pelvis-height grid


@dataclass(frozen=True)
class GaitTruth:
    """What the walker really did.

    Attributes
    ----------
    events : GaitEvents
        Foot strikes (heel sphere reaches the floor) and foot offs (forefoot sphere leaves
        it) inside the trial, exact times.
    stride_time_s, speed_mm_s, stance_fraction, step_width_mm, step_length_mm : float
        The walker's nominal gait (the same on both sides; stride and step length along a
        straight path).
    spheres_mm : dict
        ``"left_heel"``, ``"left_ball"``, ``"left_tip"``, ``"right_..."`` -> (n_fields, 3)
        centres of the spheres the foot touches the floor with (heel, metatarsal heads,
        toe tip), per field; ``sphere_radius_mm`` gives their radii. The floor is z = 0.
    """

    events: GaitEvents
    stride_time_s: float
    speed_mm_s: float
    stance_fraction: float
    step_width_mm: float
    step_length_mm: float
    spheres_mm: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    sphere_radius_mm: dict[str, float] = field(default_factory=dict)

    def nominal(self) -> dict[str, float]:
        """Nominal spatiotemporal parameters (units as in :mod:`kisscal.gait.spatiotemporal`)."""
        return {
            "cadence": 120.0 / self.stride_time_s,
            "walking_speed": self.speed_mm_s / 1000.0,
            "stride_time": self.stride_time_s,
            "stride_length": 2.0 * self.step_length_mm / 1000.0,
            "step_length": self.step_length_mm / 1000.0,
            "step_width": self.step_width_mm / 1000.0,
            "stance": 100.0 * self.stance_fraction,
            "swing": 100.0 * (1.0 - self.stance_fraction),
            "double_support": 100.0 * (2.0 * self.stance_fraction - 1.0),
        }


def _plane_frame(heel: NDArray, fore: NDArray, hip: NDArray, outward: NDArray) -> tuple:
    """Foot axes: forward, up and the outward normal of the plane of sole line and hip."""
    d = fore - heel
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = np.cross(d, hip - heel)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n *= np.sign(np.sum(n * outward, axis=1))[:, None]
    e = np.cross(n, d)
    e *= np.sign(e[:, 2])[:, None]
    c, s = np.cos(SOLE_TILT), np.sin(SOLE_TILT)
    return c * d + s * e, -s * d + c * e, n


def _ankle(heel: NDArray, fwd: NDArray, up: NDArray, b: Body) -> NDArray:
    return heel + b.k * (40.0 * fwd + 40.0 * up)


def _leg(hip: NDArray, heel: NDArray, fore: NDArray, outward: NDArray, b: Body) -> dict:
    """Joint centres and KISS markers of one leg (the kinematic walker's marker offsets)."""
    fwd, up, n = _plane_frame(heel, fore, hip, outward)
    ankle = _ankle(heel, fwd, up, b)
    reach = ankle - hip
    d = np.linalg.norm(reach, axis=1, keepdims=True)
    u = reach / d
    w = np.cross(n, u)
    w *= np.sign(np.sum(w * fwd, axis=1))[:, None]  # knee in front of the hip-ankle line
    cos_h = np.clip((b.thigh**2 + d**2 - b.shank**2) / (2 * b.thigh * d), -1.0, 1.0)
    knee = hip + b.thigh * (cos_h * u + np.sqrt(1 - cos_h**2) * w)
    thigh_u = (knee - hip) / b.thigh
    shank_u = (ankle - knee) / b.shank
    k = b.k
    return {
        "hip": hip,
        "knee": knee,
        "ankle": ankle,
        "heel_end": heel,
        "toe_end": fore,
        "THI": hip + 0.55 * b.thigh * thigh_u + 95 * k * n,
        "KNE": knee + 70 * k * n,
        "TIB": knee + 0.5 * b.shank * shank_u + 70 * k * n,
        "ANK": ankle + 60 * k * n,
        "HEE": ankle - k * (85 * fwd + 30 * up),
        "TOE": ankle + k * (140 * fwd - 5 * up),
    }


def _pelvis_pose(t: NDArray, path: WalkPath, g: GaitTiming, b: Body) -> tuple[NDArray, NDArray]:
    """Pelvis origin on the floor (n, 3, height 0) and its forward axis (n, 3)."""
    u = g.speed * t
    phase = 2 * np.pi * (t - g.first_strike["right"]) / g.period_s
    theta = path.theta(u)
    yaw = theta + np.radians(4.0) * np.sin(phase)
    normal = np.stack([-np.sin(theta), np.cos(theta)], axis=1)
    xy = path.point(u) - (b.sway * np.sin(phase))[:, None] * normal
    origin = np.column_stack([xy, np.zeros(len(t))])
    forward = np.column_stack([np.cos(yaw), np.sin(yaw), np.zeros(len(t))])
    return origin, forward


def _hips(origin: NDArray, forward: NDArray, b: Body) -> dict[str, NDArray]:
    left = np.column_stack([-forward[:, 1], forward[:, 0], np.zeros(len(forward))])
    return {"right": origin - b.hip_half * left, "left": origin + b.hip_half * left}


def _pelvis_height(
    t_end: float, path: WalkPath, prints: dict, g: GaitTiming, b: Body
) -> CubicSpline:
    """Pelvis height over time: as high as both legs reach with 7 degrees of knee flexion."""
    t = np.arange(-g.period_s, t_end + g.period_s, _DENSE_S)
    origin, forward = _pelvis_pose(t, path, g, b)
    hips = _hips(origin, forward, b)
    reach = (b.thigh + b.shank) * np.cos(np.radians(3.5))
    highest = np.full(len(t), np.inf)
    for side in ("left", "right"):
        heel, fore, _ = sole_pose(t, prints[side], g, b)
        raised = hips[side] + [0.0, 0.0, 0.9 * reach]  # frame only needs the side of the hip
        fwd, up, _ = _plane_frame(heel, fore, raised, hips[side] - origin)
        ankle = _ankle(heel, fwd, up, b)
        flat = np.linalg.norm((hips[side] - ankle)[:, :2], axis=1)
        highest = np.minimum(highest, ankle[:, 2] + np.sqrt(reach**2 - flat**2))
    smooth = gaussian_filter1d(highest, 0.04 * g.period_s / _DENSE_S, mode="nearest")
    smooth -= max(0.0, float(np.max(smooth - highest))) + 2.0 * b.k
    return CubicSpline(t, smooth)


def _timing(speed: float, height_mm: float, phase: float) -> GaitTiming:
    """Normal walking at ``speed`` (mm/s) for a subject of ``height_mm``."""
    k = height_mm / REFERENCE_HEIGHT_MM
    step = float(np.sqrt(_WALK_RATIO * k * speed * 60.0))
    cadence = speed * 60.0 / step
    period = 120.0 / cadence
    stance = float(np.clip(0.665 - 0.045 * speed / 1000.0, 0.58, 0.66))
    right = -phase * period
    return GaitTiming(
        period_s=period,
        stance=stance,
        speed=speed,
        step=step,
        width=0.055 * height_mm,
        first_strike={"right": right, "left": right + 0.5 * period},
    )


def grounded_walk(
    names: tuple[str, ...],
    n_fields: int,
    rate_hz: float,
    speed_mm_s: float,
    height_mm: float,
    heading: float,
    start_xy: NDArray,
    phase: float,
    turn_rad: float = 0.0,
) -> tuple[dict[str, NDArray], NDArray, NDArray, GaitTruth]:
    """Markers (name -> (n, 3)), capsules (n, c, 2, 3), radii (c,) and the truth.

    ``start_xy`` is the pelvis' floor position at field 0, ``heading`` its walking
    direction (rad from +X towards +Y), ``phase`` the right leg's gait-cycle phase at
    field 0 (0 = right foot strike), ``turn_rad`` the change of heading over the trial.
    """
    b = Body(height_mm / REFERENCE_HEIGHT_MM)
    t = np.arange(n_fields) / rate_hz
    t_end = float(t[-1])
    g = _timing(speed_mm_s, height_mm, phase)
    path = WalkPath(start_xy, heading, turn_rad / max(speed_mm_s * t_end, 1e-9))
    prints = footprints(path, g, t_end)
    height = _pelvis_height(t_end, path, prints, g, b)
    origin, forward = _pelvis_pose(t, path, g, b)
    origin[:, 2] = height(t)
    left = np.column_stack([-forward[:, 1], forward[:, 0], np.zeros(n_fields)])
    up = np.array([0.0, 0.0, 1.0])

    def pelvis_point(p: NDArray) -> NDArray:
        q = b.k * np.asarray(p, float)
        return origin + q[0] * forward + q[1] * left + q[2] * up

    hips = _hips(origin, forward, b)
    legs, spheres = {}, {}
    for side, sign in (("R", -1.0), ("L", 1.0)):
        full = "left" if side == "L" else "right"
        heel, ball, tip = sole_pose(t, prints[full], g, b)
        legs[side] = _leg(hips[full], heel, ball, sign * left, b)
        spheres[f"{full}_heel"], spheres[f"{full}_ball"], spheres[f"{full}_tip"] = heel, ball, tip
    markers = {
        n: pelvis_point(PELVIS_MARKERS[n]) if n in PELVIS_MARKERS else legs[n[0]][n[1:]]
        for n in names
    }
    caps = [
        np.stack(
            [
                pelvis_point([0.0, -PELVIS_HALF_LENGTH_MM, 40.0]),
                pelvis_point([0.0, PELVIS_HALF_LENGTH_MM, 40.0]),
            ],
            axis=1,
        )
    ]
    radii = [PELVIS_RADIUS_MM * b.k]
    for side in "RL":
        leg = legs[side]
        for a, c, r in (
            ("hip", "knee", 65.0),
            ("knee", "ankle", 45.0),
            ("heel_end", "toe_end", 30.0),
        ):
            caps.append(np.stack([leg[a], leg[c]], axis=1))
            radii.append(r * b.k)
    truth = _truth(prints, g, t_end, rate_hz)
    radius = {"heel": b.radius, "ball": b.radius, "tip": b.tip}
    truth = replace(
        truth, spheres_mm=spheres, sphere_radius_mm={k: radius[k.split("_")[1]] for k in spheres}
    )
    return markers, np.stack(caps, axis=1), np.asarray(radii), truth


def _truth(prints: dict, g: GaitTiming, t_end: float, rate: float) -> GaitTruth:
    times = {}
    for side in ("left", "right"):
        strikes = prints[side][0]
        offs = strikes + g.stance_s
        times[(side, "foot_strike")] = strikes[(strikes >= 0) & (strikes <= t_end)]
        times[(side, "foot_off")] = offs[(offs >= 0) & (offs <= t_end)]
    return GaitTruth(
        events=GaitEvents.from_times(times, rate),
        stride_time_s=g.period_s,
        speed_mm_s=g.speed,
        stance_fraction=g.stance,
        step_width_mm=g.width,
        step_length_mm=g.step,
    )
