"""Every default of the gait stage (events and spatiotemporal parameters), in one place."""

from __future__ import annotations

from dataclasses import dataclass

from kisscal.params import Params, param


@dataclass(frozen=True)
class GaitParams(Params):
    """Parameters of gait event detection (see :func:`kisscal.gait.detect_events`).

    Attributes
    ----------
    derivative_ms : float
        Span of the local quadratic fits (Savitzky-Golay) that give marker velocities;
        at least 5 samples are used whatever the rate.
    direction_s : float
        SD of the Gaussian that smooths the pelvis velocity into the local direction of
        progression (turns slower than this are followed).
    min_speed_mm_s : float
        Below this pelvis speed the subject is not walking: no events are looked for.
    hysteresis : float
        A heel (toe) must move forward faster than the pelvis by this fraction of the
        walking speed, and then slower by as much, for a stride to count (Zeni et al.
        2008's zero crossing, made immune to noise).
    hold_s : float
        ... and the heel (toe) must then stay behind (ahead) that long: a brief dip of
        the relative velocity is not a change of phase.
    strike_window : (float, float)
        Where the heel's lowest point is looked for around the coarse foot strike, as
        fractions of the stride time (the coarse event comes 20-70 ms early).
    off_window : (float, float)
        Where the foot's fastest plantarflexion is looked for around the coarse foot off
        (the coarse event comes 10-35 ms late), fractions of the stride time.
    strike_sink : float
        A heel marker may sink on through stance, its height lowest at the end of the
        strike window: its lowest is then looked for up to this fraction of the stride
        after the coarse foot strike (before the heel rises).
    strike_floor_mm : float
        The heel has reached the floor at the first sample of the window within this of
        its lowest there: the corner of its height is looked for around that sample, not
        around the lowest one (a heel marker can sink a few mm more as the foot rolls
        down to foot flat, 30-100 ms after the strike); nor after it had come to rest,
        sinking less than this over the next ``strike_search_ms``, once the toes stopped
        rising (a heel marker sinking on under the load).
    tip_ahead_mm : float
    tip_floor_mm : (float, float)
        A flat or forefoot landing: the tip of the foot lies ``tip_ahead_mm`` ahead of
        the toe marker on the heel-to-toe line (toe markers sit over the metatarsal
        heads, the toes' pads 30-50 mm ahead), and the foot strikes where the tip comes
        within ``tip_floor_mm[0]`` of its height at foot flat on its last descent from
        ``tip_floor_mm[1]`` up (more than marker noise), if that is before the heel
        lands (:func:`kisscal.gait.landing.forefoot_landing`).
    strike_fit_ms, strike_search_ms : float
        Half width of the window over which the corner of the heel's height is fitted,
        and how far from the sample where the heel reached the floor the corner may lie.
    off_fit_ms, off_search_ms : float
        The same for the corner of the foot's pitch rate at foot off, around the
        fastest plantarflexion of the smoothed pitch rate.
    off_recovery : (float, float)
    off_sharp_ms : (float, float)
    filtered_mm : float
        Trajectories filtered before they were saved round the corner of the pitch rate
        at foot off: when the pitch rate takes longer than ``off_sharp_ms`` (or one
        field) after the corner to recover the first fraction of its fastest
        plantarflexion, foot off is taken where it has recovered the second. The first
        time is for raw trajectories, whose noise alone can delay the recovery (0.5 mm:
        up to 15 ms), the second for trajectories filtered before they were saved
        (pelvis noise under ``filtered_mm``: :func:`kisscal.gait.events.noise_mm`; raw
        optical data 0.02-0.3 mm, Nexus-filtered 0.003-0.01 mm), where a corner 13-15 ms
        before the first level lies 15-35 ms before foot off. Chosen on half of the real
        trials (fixtures/real/gait and six biomechZoo subjects), checked on the other
        half (``python -m tests.gait.folder_events``).
    ankle_heel_mm : float
        A foot without a heel marker gets a heel stand-in this far behind its ankle
        marker, on the line from the toe marker through the ankle (lateral malleolus to
        the heel's contact, about 40-60 mm in adults): see
        :func:`kisscal.gait.markers.heel_from_ankle`.
    heel_down_mm : float
        A heel within this of its lowest is down on the ground (mid-stance): on a
        treadmill its velocity relative to the pelvis gives the belt's speed.
    min_trial_s : float
        A shorter trial is reported as too short for a full stride.
    max_missing : float
        A side without a full stride names its heel or toe marker, or the pelvis,
        missing in more than this fraction of the fields (gaps hide events).
    human_cadence : (float, float)
        Cadence (steps/min) outside which no one walks: a trial's mean cadence outside it
        points to a wrong ``[session] rate_hz`` (times scale with it), and the log says so.
    human_speed : (float, float)
        The same for the walking speed (m/s).
    human_walk_ratio : (float, float)
        The same for the walk ratio, mean step length over mean cadence (m per
        step/min): about 0.0064 in adults at any speed, lower in children and short
        steps (Sekiya & Nagasaki 1998). A rate given too low (30 for 50 Hz) leaves
        cadence and speed in the range of slow, pathological walking, but not the walk
        ratio: step lengths do not change with the rate, the cadence does.
    """

    section = "gait"
    derivative_ms: float = param(40.0, unit="ms", gt=0)
    direction_s: float = param(0.4, unit="s", gt=0)
    min_speed_mm_s: float = param(150.0, unit="mm/s", gt=0)
    hysteresis: float = param(0.3, gt=0, lt=1)
    hold_s: float = param(0.1, unit="s", gt=0)
    strike_window: tuple[float, float] = param((-0.05, 0.2), ge=-0.5, le=0.5)
    off_window: tuple[float, float] = param((-0.2, 0.05), ge=-0.5, le=0.5)
    strike_sink: float = param(0.4, gt=0, le=0.6)
    strike_floor_mm: float = param(1.0, unit="mm", gt=0)
    tip_ahead_mm: float = param(40.0, unit="mm", ge=0)
    tip_floor_mm: tuple[float, float] = param((1.0, 3.0), unit="mm", gt=0)
    strike_fit_ms: float = param(80.0, unit="ms", gt=0)
    strike_search_ms: float = param(30.0, unit="ms", gt=0)
    off_fit_ms: float = param(120.0, unit="ms", gt=0)
    off_search_ms: float = param(40.0, unit="ms", gt=0)
    off_recovery: tuple[float, float] = param((0.2, 0.32), gt=0, lt=1)
    off_sharp_ms: tuple[float, float] = param((15.0, 13.0), unit="ms", gt=0)
    filtered_mm: float = param(0.02, unit="mm", gt=0)
    ankle_heel_mm: float = param(40.0, unit="mm", ge=0)
    heel_down_mm: float = param(10.0, unit="mm", gt=0)
    min_trial_s: float = param(1.5, unit="s", gt=0)
    max_missing: float = param(0.5, ge=0, le=1)
    human_cadence: tuple[float, float] = param((30.0, 200.0), unit="steps/min", gt=0)
    human_speed: tuple[float, float] = param((0.1, 3.0), unit="m/s", gt=0)
    # 18 real trials of fixtures/real/gait: 0.0026-0.0074; a rate 0.6x too low: x 1.67
    human_walk_ratio: tuple[float, float] = param((0.002, 0.0095), unit="m/(steps/min)", gt=0)

    def check(self) -> None:
        for name in (
            "strike_window",
            "off_window",
            "tip_floor_mm",
            "human_cadence",
            "human_speed",
            "human_walk_ratio",
        ):
            lo, hi = getattr(self, name)
            if not lo < hi:
                self.fail(f"{name} must be (earlier, later), got {(lo, hi)!r}")


#: The defaults, shared (frozen).
DEFAULT_PARAMS = GaitParams()
