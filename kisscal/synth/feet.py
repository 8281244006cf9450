"""The grounded walker's feet: where each foot is, from its footprints, at any time.

Each foot is the KISS walker's rigid foot (a capsule of radius 30 mm from the heel end to
the ball, markers where the kinematic walker puts them) plus toes 55 mm long, and goes
through the three rockers of stance without slipping (Perry 1992):

* heel rocker, from foot strike (the heel sphere touches the floor) to foot flat at the
  end of the first double support: the heel sphere rolls while the sole pitches down
  from 20 degrees, fastest right after contact (foot slap);
* foot flat until heel rise at 52 % of stance (31 % of the cycle at 60 % stance);
* forefoot rocker: the foot turns about the ball (metatarsal heads), faster and faster,
  to -65 degrees at foot off; in the last 6 % of the cycle the toes roll up 25 degrees
  about their tip and lift the ball (walking5.c3d: the second metatarsal marker rises
  60-70 ms before its force plate's foot off). Foot off: the toe tip leaves the floor.

In swing the ball follows a quintic path from foot off (position and velocity continuous;
the push-off ends, so the foot's pitch acceleration changes sign and the ball is flung
forward) to the next footprint, where the heel lands moving down at 0.18 and forward at
0.05 times the walking speed, still braking hard (walking5.c3d: 0.19, 0.0-0.4 and about
60 m/s^2 in the last 20 ms). With these, the published kinematic event criteria fall
where they fall on walking5.c3d against its force plates (Zeni et al. 2008's crossings
20-30 ms before foot strike and 15-20 ms after foot off).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

_HS_PITCH = np.radians(20.0)  # sole pitch at foot strike (toe up)
_TO_PITCH = np.radians(65.0)  # sole pitch at foot off (toe down)
_TOE_LIFT = np.radians(25.0)  # toes' rise about their tip over the toe roll
_HEEL_RISE = 0.52  # of stance
_TOE_ROLL_S = 0.06  # of the cycle: the toes roll before foot off (walking5.c3d: 0.06-0.07)
_LANDING = (0.05, 0.18)  # forward, downward heel speed at contact / walking speed
_LANDING_DECEL = 24.0  # heel deceleration at contact, in walking speeds per swing time
_LAUNCH = 6.0  # forward acceleration the ball gains at foot off, walking speeds per swing time
_SWING_PITCH_ACC = 250.0  # rad/s^2 at the start of swing: the push-off has ended


@dataclass(frozen=True)
class Body:
    """Lengths (mm) scaled to the walker's stature."""

    k: float  # stature / reference

    def __getattr__(self, name: str) -> float:
        base = {
            "thigh": 430.0,
            "shank": 420.0,
            "hip_half": 85.0,
            "radius": 30.0,
            "sway": 15.0,
            "clearance": 25.0,
            "toe": 55.0,  # ball (metatarsal heads) to toe tip
            "tip": 10.0,  # toe tip radius
        }
        if name in base:
            return base[name] * self.k
        raise AttributeError(name)

    @property
    def sole(self) -> float:  # heel sphere centre to forefoot sphere centre
        return float(np.hypot(170.0, 10.0)) * self.k


SOLE_TILT = float(np.arctan2(10.0, 170.0))  # sole line below the foot's forward axis


@dataclass(frozen=True)
class GaitTiming:
    period_s: float
    stance: float
    speed: float  # mm/s
    step: float  # mm
    width: float  # mm
    first_strike: dict[str, float]  # side -> time of a foot strike (s)

    @property
    def flat_s(self) -> float:  # foot flat after the first double support
        return (self.stance - 0.5) * self.period_s

    @property
    def heel_rise_s(self) -> float:
        return _HEEL_RISE * self.stance * self.period_s

    @property
    def stance_s(self) -> float:
        return self.stance * self.period_s


class WalkPath:
    """The pelvis' path on the floor: start, heading and a constant curvature."""

    def __init__(self, start_xy: NDArray, heading: float, curvature: float) -> None:
        self.start, self.heading, self.curvature = np.asarray(start_xy, float), heading, curvature

    def theta(self, u: NDArray) -> NDArray:
        return self.heading + self.curvature * np.asarray(u, float)

    def point(self, u: NDArray) -> NDArray:
        u = np.asarray(u, float)
        th = self.theta(u)
        if abs(self.curvature) < 1e-12:
            d = u[..., None] * np.stack([np.cos(th), np.sin(th)], axis=-1)
        else:
            c = self.curvature
            d = np.stack(
                [(np.sin(th) - np.sin(self.heading)) / c, (np.cos(self.heading) - np.cos(th)) / c],
                axis=-1,
            )
        return self.start + d


def _pitch_stance(tau: NDArray, g: GaitTiming) -> tuple[NDArray, NDArray]:
    """Sole pitch (rad, toe up positive) and its rate over stance time ``tau`` (s)."""
    alpha, rate = np.zeros_like(tau), np.zeros_like(tau)
    heel = tau < g.flat_s
    q = tau[heel] / g.flat_s
    alpha[heel] = _HS_PITCH * (1 - q) ** 2
    rate[heel] = -2 * _HS_PITCH * (1 - q) / g.flat_s
    fore = tau > g.heel_rise_s
    span = g.stance_s - g.heel_rise_s
    q = (tau[fore] - g.heel_rise_s) / span
    alpha[fore] = -_TO_PITCH * q**3
    rate[fore] = -3 * _TO_PITCH * q**2 / span
    return alpha, rate


def _toe_rise(tau: NDArray, g: GaitTiming) -> tuple[NDArray, NDArray, NDArray]:
    """Toes' rise about their tip (rad) over stance time ``tau``, with its two derivatives."""
    span = _TOE_ROLL_S * g.period_s
    q = np.clip((tau - (g.stance_s - span)) / span, 0.0, None)
    return _TOE_LIFT * q**2, 2 * _TOE_LIFT * q / span, np.where(q > 0, 2 * _TOE_LIFT / span**2, 0.0)


def _toe_tilt(b: Body) -> float:
    """Tilt of the flat toes: from the ball's centre (radius 30 mm) down to the tip's."""
    return float(np.arcsin((b.radius - b.tip) / b.toe))


def _direction(angle: NDArray, theta: NDArray | float) -> NDArray:
    """Unit vectors pitched by ``angle`` (up positive) along headings ``theta``."""
    theta = np.broadcast_to(theta, np.shape(angle))
    c = np.cos(angle)
    return np.stack([c * np.cos(theta), c * np.sin(theta), np.sin(angle)], axis=-1)


def _stance_sole(
    tau: NDArray, foot: NDArray, theta: float, g: GaitTiming, b: Body
) -> tuple[NDArray, NDArray, NDArray]:
    """Heel, ball and toe-tip sphere centres (n, 3) of a foot that struck at ``foot``.

    Heel rocker: the heel sphere rolls. Forefoot rocker: the foot turns about the ball
    (the metatarsal heads) with the toes flat; in the toe roll the toes turn up about
    their tip and lift the ball. ``tau`` is the time since foot strike (s).
    """
    alpha, _ = _pitch_stance(tau, g)
    rise = _toe_rise(tau, g)[0]
    h = np.array([np.cos(theta), np.sin(theta), 0.0])
    z = np.array([0.0, 0.0, 1.0])
    along = _direction(alpha, theta)
    tilt = _toe_tilt(b)
    rolled = foot + b.radius * z + (b.radius * (_HS_PITCH - np.clip(alpha, 0.0, None)))[:, None] * h
    ball_flat = foot + b.radius * z + (b.radius * _HS_PITCH + b.sole) * h
    tip = ball_flat + b.toe * np.cos(tilt) * h + (b.tip - b.radius) * z
    phi = (tilt + rise)[:, None]
    ball = tip + b.toe * (-np.cos(phi) * h + np.sin(phi) * z)
    on_heel = (alpha >= 0)[:, None]
    heel = np.where(on_heel, rolled, ball - b.sole * along)
    ball = np.where(on_heel, rolled + b.sole * along, ball)
    neutral_tip = ball + b.toe * _direction(alpha - tilt, theta)
    tip = np.where(on_heel, neutral_tip, tip)
    return heel, ball, tip


def _quintic(p0, v0, a0, p1, v1, a1, duration: float, tau: NDArray) -> NDArray:
    """Quintic Hermite through end values, rates and accelerations, at times ``tau``."""
    s = (tau / duration)[:, None]
    p0, v0, a0 = np.atleast_1d(p0), np.atleast_1d(v0) * duration, np.atleast_1d(a0) * duration**2
    p1, v1, a1 = np.atleast_1d(p1), np.atleast_1d(v1) * duration, np.atleast_1d(a1) * duration**2
    h = [
        1 - 10 * s**3 + 15 * s**4 - 6 * s**5,
        s - 6 * s**3 + 8 * s**4 - 3 * s**5,
        0.5 * (s**2 - 3 * s**3 + 3 * s**4 - s**5),
        10 * s**3 - 15 * s**4 + 6 * s**5,
        -4 * s**3 + 7 * s**4 - 3 * s**5,
        0.5 * (s**3 - 2 * s**4 + s**5),
    ]
    return h[0] * p0 + h[1] * v0 + h[2] * a0 + h[3] * p1 + h[4] * v1 + h[5] * a1


def _swing_sole(
    tau: NDArray, start: tuple, end: tuple, g: GaitTiming, b: Body
) -> tuple[NDArray, NDArray, NDArray]:
    """Heel, ball and toe-tip centres in swing, ``tau`` s after foot off.

    ``start`` = (footprint, heading) of the foot leaving, ``end`` = those of its next
    strike. The ball leaves with the velocity and acceleration the toe roll gave it; the
    heel lands at the next footprint moving forward and down, still decelerating.
    """
    (f0, th0), (f1, th1) = start, end
    duration = g.period_s - g.stance_s
    z = np.array([0.0, 0.0, 1.0])
    h0 = np.array([np.cos(th0), np.sin(th0), 0.0])
    h1 = np.array([np.cos(th1), np.sin(th1), 0.0])
    off = np.array([g.stance_s])
    _, ball0, _ = _stance_sole(off, f0, th0, g, b)
    _, rate0 = _pitch_stance(off, g)
    rise, rise_rate, rise_acc = (float(x[0]) for x in _toe_rise(off, g))
    phi = _toe_tilt(b) + rise
    radial = np.sin(phi) * h0 + np.cos(phi) * z
    v0 = b.toe * rise_rate * radial
    a0 = b.toe * (rise_acc * radial + rise_rate**2 * (np.cos(phi) * h0 - np.sin(phi) * z))
    a0 = a0 + _LAUNCH * g.speed / duration * h0
    heel1 = f1 + b.radius * z
    ball1 = heel1 + b.sole * _direction(np.array(_HS_PITCH), th1)
    landing = g.speed * (_LANDING[0] * h1 - _LANDING[1] * z)
    brake = -_LANDING_DECEL * g.speed / duration * h1
    ball = _quintic(ball0[0], v0, a0, ball1, landing, brake, duration, tau)
    s = tau / duration
    ball = ball + (b.clearance * 64 * s**3 * (1 - s) ** 3)[:, None] * z
    alpha = _quintic(-_TO_PITCH, rate0[0], _SWING_PITCH_ACC, _HS_PITCH, 0.0, 0.0, duration, tau)
    alpha = alpha[:, 0]
    dth = np.angle(np.exp(1j * (th1 - th0)))
    theta = th0 + dth * _quintic(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, duration, tau)[:, 0]
    # the toes fold back from their dorsiflexion at foot off during the first 40 % of swing
    bend0 = _TO_PITCH - rise
    bend = _quintic(bend0, -rate0[0] - rise_rate, 0.0, 0.0, 0.0, 0.0, 0.4 * duration, tau)
    bend = np.where(s < 0.4, bend[:, 0], 0.0)
    tip = ball + b.toe * _direction(alpha - _toe_tilt(b) + bend, theta)
    return ball - b.sole * _direction(alpha, theta), ball, tip


def footprints(path: WalkPath, g: GaitTiming, t_end: float) -> dict[str, tuple]:
    """Per side: strike times, heel contact points and headings, a stride beyond each end."""
    out = {}
    lead = 0.40 * g.step  # heel ahead of the pelvis at foot strike
    for side, sign in (("right", -1.0), ("left", 1.0)):
        t0 = g.first_strike[side]
        k = np.arange(
            np.floor((-2 * g.period_s - t0) / g.period_s),
            np.ceil((t_end + 2 * g.period_s - t0) / g.period_s) + 1,
        )
        times = t0 + k * g.period_s
        u = g.speed * times + lead
        theta = path.theta(u)
        normal = np.stack([-np.sin(theta), np.cos(theta)], axis=1)
        xy = path.point(u) + sign * 0.5 * g.width * normal
        out[side] = (times, np.column_stack([xy, np.zeros(len(u))]), theta)
    return out


def sole_pose(
    t: NDArray, prints: tuple, g: GaitTiming, b: Body
) -> tuple[NDArray, NDArray, NDArray]:
    """Heel, ball and toe-tip sphere centres (n, 3) of one foot at times ``t``."""
    times, feet, theta = prints
    k = np.searchsorted(times, t, side="right") - 1
    out = np.empty((3, len(t), 3))
    for i in np.unique(k):
        sel = np.flatnonzero(k == i)
        tau = t[sel] - times[i]
        stance = tau < g.stance_s
        if stance.any():
            out[:, sel[stance]] = _stance_sole(tau[stance], feet[i], theta[i], g, b)
        if (~stance).any():
            out[:, sel[~stance]] = _swing_sole(
                tau[~stance] - g.stance_s, (feet[i], theta[i]), (feet[i + 1], theta[i + 1]), g, b
            )
    return out[0], out[1], out[2]
