"""Synthetic gait trials with true foot contacts, and scoring of detected events against them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kisscal.gait import GaitEvents, GaitMarkers, detect_events, gait_markers
from kisscal.gait.spatiotemporal import Spatiotemporal, spatiotemporal_parameters
from kisscal.gait.table import EVENTS, SIDES
from kisscal.markersets import marker_set
from kisscal.synth.motion import Motion, walking_trial

NOISE_MM = 0.5
#: Detected events further than this from every true one are extra.
MATCH_S = 0.15


@dataclass
class Trial:
    motion: Motion
    markers: GaitMarkers  # noisy
    clean: GaitMarkers
    events: GaitEvents  # detected

    @property
    def truth(self):
        return self.motion.truth


def walker(
    seed: int,
    rate_hz: float,
    heading_deg: float,
    height_m: float,
    speed_m_s: float = 1.1,
    duration_s: float = 5.0,
    turn_deg: float = 0.0,
) -> Motion:
    """The grounded walker (true contacts in ``.truth``) at a speed for a duration."""
    n = round(duration_s * rate_hz)
    return walking_trial(
        seed,
        n,
        rate_hz,
        path_mm=speed_m_s * 1000.0 * (n - 1) / rate_hz,
        model="grounded",
        height_m=height_m,
        heading_deg=heading_deg,
        turn_deg=turn_deg,
    )


def trial(
    seed: int,
    rate_hz: float,
    heading_deg: float,
    height_m: float,
    speed_m_s: float = 1.1,
    duration_s: float = 5.0,
    noise_mm: float = NOISE_MM,
    turn_deg: float = 0.0,
) -> Trial:
    """A grounded walker trial, 0.5 mm noise per coordinate, events detected."""
    m = walker(seed, rate_hz, heading_deg, height_m, speed_m_s, duration_s, turn_deg)
    rng = np.random.default_rng([seed, 77])
    noisy = m.xyz_mm + rng.normal(0.0, noise_mm, m.xyz_mm.shape)
    kiss = marker_set("kiss")
    gm = gait_markers(dict(zip(m.names, noisy.transpose(1, 0, 2), strict=True)), rate_hz, kiss)
    clean = gait_markers(
        dict(zip(m.names, m.xyz_mm.transpose(1, 0, 2), strict=True)), rate_hz, kiss
    )
    return Trial(m, gm, clean, detect_events(gm))


@dataclass
class Score:
    errors_s: dict[str, list[float]]  # event -> detected - true, matched pairs
    missed: dict[str, int]  # true events of full strides with no detection
    extra: dict[str, int]  # detections with no true event near


def score(found: GaitEvents, truth, t_end: float) -> Score:
    """Match detected to true events per side and kind (nearest, one to one)."""
    period = truth.stride_time_s
    errors = {e: [] for e in EVENTS}
    missed = dict.fromkeys(EVENTS, 0)
    extra = dict.fromkeys(EVENTS, 0)
    for side in SIDES:
        for event in EVENTS:
            d = list(found.times(side, event))
            for t in truth.events.times(side, event):
                full = t - 0.35 * period >= 0.0 and t + 0.25 * period <= t_end
                k = int(np.argmin([abs(x - t) for x in d])) if d else -1
                if k >= 0 and abs(d[k] - t) <= MATCH_S:
                    errors[event].append(d.pop(k) - t)
                elif full:
                    missed[event] += 1
            extra[event] += len(d)
    return Score(errors, missed, extra)


def true_spatiotemporal(tr: Trial) -> Spatiotemporal:
    """The parameters of the noise-free markers at the true contact instants."""
    return spatiotemporal_parameters(tr.truth.events, tr.clean)


def measured_spatiotemporal(tr: Trial) -> Spatiotemporal:
    return spatiotemporal_parameters(tr.events, tr.markers)


def grid(n: int, seed: int = 0) -> list[tuple[float, float, float]]:
    """``n`` (heading deg, height m, speed m/s): headings spread over 360 degrees."""
    rng = np.random.default_rng(seed)
    headings = (np.arange(n) + rng.uniform(0, 1)) * 360.0 / n
    heights = 1.5 + 0.4 * (np.arange(n) * 0.618034 % 1.0)
    speeds = rng.uniform(0.7, 1.4, n)
    return [
        (float(a), float(h), float(v)) for a, h, v in zip(headings, heights, speeds, strict=True)
    ]
