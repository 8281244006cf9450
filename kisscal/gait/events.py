"""Foot strike and foot off from marker trajectories, any walking direction.

Two steps per event (the whole account, with the measured accuracy, is the section
"Gait events and spatiotemporal parameters" of ``docs/methods.md``):

1. **Strides** (coarse): Zeni et al. 2008's velocity method. The heel's velocity relative
   to the pelvis, along the local direction of progression (:func:`progression`; on a
   treadmill the feet's, :func:`belt_speed`), turns from forward to backward just before
   foot strike, the toe's from backward to forward just after foot off; a hysteresis
   rejects noise, and a stride cut by the trial's ends or a gap gives no event (but a
   foot seen landing before its markers are lost keeps its strike).
2. **Instants** (fine), near each coarse event, with sub-field precision, each the
   corner of a broken-curve fit (two quadratics meeting at the event): foot strike where
   the heel's height turns as the heel meets the floor (Hreljac & Marshall 2000), looked
   for from where the heel comes to rest (Ghoussayni et al. 2004), or where the tip of a
   foot landing flat or on its forefoot reaches the floor first (Perry 1992); foot off
   where the foot's pitch rate stops at the end of push-off (a kinematic cousin of
   O'Connor et al. 2007's foot velocity algorithm), or, on trajectories low-pass filtered
   before they were saved, where the pitch rate has recovered part of its fastest
   plantarflexion.

Each detection says why it lacks events or full strides (:func:`explain`): too short,
a marker missing, no walking, no heel-strike pattern, a side without two strikes.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.gait.landing import extremum, foot_strikes
from kisscal.gait.markers import GaitMarkers, gait_markers  # noqa: F401 (doctest)
from kisscal.gait.params import DEFAULT_PARAMS, GaitParams
from kisscal.gait.signals import (
    derivative,
    hysteresis_crossings,
    kink_time,
    smooth,
)
from kisscal.gait.table import SIDES, GaitEvents


def progression(
    markers: GaitMarkers, params: GaitParams = DEFAULT_PARAMS
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Local direction of progression (n, 2), unit, and pelvis velocity (n, 3) in mm/s.

    The pelvis velocity is the mean velocity of the pelvis markers present at each
    field (where none is, within ``params.direction_s`` of a field where one is, that
    field's: walking speed changes little over it, and the feet may be seen before the
    pelvis); the direction is its horizontal part smoothed over ``params.direction_s``.
    Where the pelvis moves slower than ``params.min_speed_mm_s`` but the feet still walk
    under it (a treadmill: :func:`belt_speed`), the direction is the feet's
    (:func:`foot_direction`); where neither moves, NaN (no walking, no events).
    """
    rate = markers.rate_hz
    velocities = np.stack([derivative(p, rate, params.derivative_ms) for p in markers.pelvis])
    with np.errstate(invalid="ignore"), _quiet():
        pelvis_v = np.nanmean(velocities, axis=0)
    pelvis_v = _hold(pelvis_v, round(params.direction_s * rate))
    flat = smooth(pelvis_v[:, :2], params.direction_s * rate)
    speed = np.linalg.norm(flat, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = flat / speed[:, None]
    still = ~(speed >= params.min_speed_mm_s)
    direction[still] = np.nan
    if still.any():
        feet = foot_direction(markers, params)
        if belt_speed(markers, feet, params) >= params.min_speed_mm_s:
            direction[still] = feet[still]
    return direction, pelvis_v


def _hold(v: NDArray, reach: int) -> NDArray[np.float64]:
    """``v`` (n, k) with each row missing within ``reach`` rows of a valid one given the
    nearest valid row's value."""
    ok = np.all(np.isfinite(v), axis=1)
    if ok.all() or not ok.any():
        return v
    valid = np.flatnonzero(ok)
    i = np.arange(len(v))
    k = np.searchsorted(valid, i).clip(1, len(valid) - 1) if len(valid) > 1 else np.zeros_like(i)
    near = np.where(np.abs(valid[k] - i) < np.abs(valid[k - 1] - i), valid[k], valid[k - 1])
    out = v.copy()
    fill = ~ok & (np.abs(near - i) <= reach)
    out[fill] = v[near[fill]]
    return out


def belt_speed(
    markers: GaitMarkers, direction: NDArray, params: GaitParams = DEFAULT_PARAMS
) -> float:
    """Speed (mm/s) at which the ground carries the feet back through the lab, along
    ``direction``: minus the median velocity of the heels while they are down (within
    ``params.heel_down_mm`` of their lowest).

    A heel down on a treadmill's belt moves with it; overground, or standing, it stands
    still (0).
    """
    forward = []
    for side in SIDES:
        heel = markers.heel[side]
        v = derivative(heel, markers.rate_hz, params.derivative_ms)
        along = np.sum(v[:, :2] * direction, axis=1)
        z = heel[:, 2]
        if np.any(np.isfinite(z)):
            with np.errstate(invalid="ignore"):
                down = z <= np.nanpercentile(z, 5) + params.heel_down_mm
            forward.append(along[down & np.isfinite(along)])
    forward = np.concatenate(forward) if forward else np.array([])
    return float(-np.median(forward)) if len(forward) else 0.0


def ground_velocity(
    markers: GaitMarkers, params: GaitParams = DEFAULT_PARAMS
) -> NDArray[np.float64]:
    """Horizontal velocity (n, 2), mm/s, of the ground the subject walks on: 0
    overground, the belt's (backwards at the walking speed) where the pelvis stands
    still in the lab and the feet walk (a treadmill)."""
    direction, pelvis_v = progression(markers, params)
    flat = np.linalg.norm(smooth(pelvis_v[:, :2], params.direction_s * markers.rate_hz), axis=1)
    belt = ~(flat >= params.min_speed_mm_s) & np.isfinite(direction[:, 0])
    out = np.zeros((markers.n_fields, 2))
    if belt.any():
        out[belt] = -belt_speed(markers, direction, params) * direction[belt]
    return out


def walking_speed(
    markers: GaitMarkers, direction: NDArray, pelvis_v: NDArray, params: GaitParams
) -> NDArray[np.float64]:
    """Walking speed (n,), mm/s: the pelvis' where it moves, else the treadmill's."""
    speed = np.linalg.norm(pelvis_v[:, :2], axis=1)
    flat = np.linalg.norm(smooth(pelvis_v[:, :2], params.direction_s * markers.rate_hz), axis=1)
    still = ~(flat >= params.min_speed_mm_s) & np.isfinite(direction[:, 0])
    if still.any():
        speed[still] = belt_speed(markers, direction, params)
    return speed


def detect_events(markers: GaitMarkers, params: GaitParams = DEFAULT_PARAMS) -> GaitEvents:
    """Foot strikes and foot offs of both sides, with sub-field times.

    Parameters
    ----------
    markers : GaitMarkers
        Pelvis, heel and toe trajectories (see :func:`kisscal.gait.gait_markers`).
    params : GaitParams

    Returns
    -------
    GaitEvents
        Table ``side, event, field, time_s``; ``time_s`` is sub-field (0 s at field 0),
        ``field`` the nearest field; ``warnings`` says why events or full strides are
        missing (:func:`explain`).

    References
    ----------
    Zeni, Richards & Higginson 2008 (velocity-based stride detection); Hreljac & Marshall
    2000 (foot strike from the heel's vertical motion); Ghoussayni, Stevens, Durham &
    Ewins 2004 (heel contact where the heel marker comes to rest); O'Connor, Thorpe,
    O'Malley & Vaughan 2007 (foot off from the foot's motion at push-off).

    Examples
    --------
    >>> from kisscal.synth.motion import walking_trial
    >>> from kisscal.markersets import marker_set
    >>> m = walking_trial(1, 400, 100.0, path_mm=4000, model="grounded", heading_deg=120)
    >>> gm = gait_markers(dict(zip(m.names, m.xyz_mm.transpose(1, 0, 2))), 100.0,
    ...                   marker_set("kiss"))
    >>> found = detect_events(gm)
    >>> true = m.truth.events
    >>> err = [abs(found.times(s, e)[:, None] - true.times(s, e)).min(axis=1)
    ...        for s in ("left", "right") for e in ("foot_strike", "foot_off")]
    >>> bool(np.concatenate(err).max() < 0.010)
    True
    """
    direction, pelvis_v = progression(markers, params)
    rate = markers.rate_hz
    t = markers.time_s
    speed = walking_speed(markers, direction, pelvis_v, params)
    times: dict[tuple[str, str], list[float]] = {}
    coarse = {side: _coarse(markers, side, direction, pelvis_v, speed, params) for side in SIDES}
    strides = np.concatenate([np.diff(c[0]) for c in coarse.values()]) / rate
    stride_s = float(np.median(strides)) if len(strides) else 1.1
    zeni_only = {}
    filtered = noise_mm(markers.pelvis) < params.filtered_mm
    for side in SIDES:
        strikes, offs = coarse[side]
        times[(side, "foot_strike")], zeni_only[side] = foot_strikes(
            t, markers.heel[side], strikes / rate, stride_s, params, markers.toe[side]
        )
        times[(side, "foot_off")] = _offs(
            t, markers.heel[side], markers.toe[side], offs / rate, stride_s, params, filtered
        )
    notes = explain(markers, times, direction, zeni_only, params)
    return GaitEvents.from_times(times, rate, notes)


def explain(
    markers: GaitMarkers,
    times: dict[tuple[str, str], list[float]],
    direction: NDArray,
    zeni_only: dict[str, int],
    params: GaitParams = DEFAULT_PARAMS,
) -> list[str]:
    """One line for each reason a trial lacks events or full strides: too short, the
    lab's z axis not up, no walking, no heel-strike pattern (foot strikes then come from
    Zeni's rule alone), a side with fewer than two foot strikes (and which of its
    markers, or the pelvis, is missing in more than ``params.max_missing`` of it)."""
    notes = []
    duration = markers.n_fields / markers.rate_hz
    if duration < params.min_trial_s:
        notes.append(
            f"the trial lasts {duration:.2f} s: too short for a full stride "
            f"(two foot strikes of one foot, at least {params.min_trial_s:g} s of walking)"
        )
    notes += _vertical(markers)
    if not np.any(np.isfinite(direction[:, 0])):
        notes.append(
            f"no walking: the pelvis moves slower than {params.min_speed_mm_s:g} mm/s and "
            "the feet do not step under it"
        )
    explained = bool(notes)
    notes += [
        f"{side}: no heel marker: foot strikes from a heel {params.ankle_heel_mm:g} mm behind "
        f"the ankle marker ({markers.names.get(f'{side}_heel', 'ankle')})"
        for side in markers.heel_from_ankle
    ]
    for side in SIDES:
        if zeni_only[side]:
            notes.append(
                f"{side}: no heel-strike pattern (the heel's height has no low point after "
                f"the swing) at {zeni_only[side]} foot strike(s), taken from Zeni's rule alone"
            )
        n = len(times[(side, "foot_strike")])
        if n < 2 and not explained:
            notes.append(
                f"no full stride on the {side}: {n} foot strike(s) found"
                + "".join(f"; {m}" for m in _missing(markers, side, params))
            )
    return notes


def _missing(markers: GaitMarkers, side: str, params: GaitParams) -> list[str]:
    """'the left heel marker (LHEE) is missing in 73 % of the fields', and the like."""
    out = []
    roles = [("pelvis", pelvis_centre(markers))]
    roles += [(f"{side}_{r}", getattr(markers, r)[side]) for r in ("heel", "toe")]
    for role, track in roles:
        missing = 1.0 - float(np.mean(np.all(np.isfinite(track), axis=1)))
        if missing > params.max_missing:
            name = markers.names.get(role, "")
            out.append(
                f"the {role.replace('_', ' ')} marker{f' ({name})' if name else ''} "
                f"is missing in {100 * missing:.0f} % of the fields"
            )
    return out


def _vertical(markers: GaitMarkers) -> list[str]:
    """A line if the pelvis is not above the heels along +z (a lab with y up, say)."""
    with np.errstate(invalid="ignore"), _quiet():
        above = np.nanmedian(
            pelvis_centre(markers) - (markers.heel["left"] + markers.heel["right"]) / 2, axis=0
        )
    if not np.all(np.isfinite(above)) or above[2] > 0.5 * np.max(np.abs(above)):
        return []
    axis = "xyz"[int(np.argmax(np.abs(above)))]
    sign = "+" if above["xyz".index(axis)] > 0 else "-"
    return [
        f"the pelvis is {abs(above['xyz'.index(axis)]):.0f} mm above the heels along "
        f"{sign}{axis}, not +z: gait events need the lab's z axis up"
    ]


def _offs(
    t: NDArray,
    heel: NDArray,
    toe: NDArray,
    coarse: NDArray,
    stride_s: float,
    params: GaitParams,
    filtered: bool = False,
):
    """Foot offs: the end of the push-off near each coarse one.

    Where the markers were recorded raw, the foot's pitch rate turns a sharp corner at
    foot off (:func:`_fastest`). Labs often low-pass filter their trajectories before
    saving them, which rounds that corner into a valley whose bottom comes 30-70 ms
    before foot off; a symmetric filter moves a level crossing on a steep slope far less
    than a corner, so when the pitch rate takes longer than ``params.off_sharp_ms`` (or
    one field; its second value where the trajectories were ``filtered``, their noise
    too low to delay the recovery: :func:`noise_mm`) to recover
    ``params.off_recovery[0]`` of its fastest plantarflexion, foot off is where it has
    recovered ``params.off_recovery[1]`` instead.
    """
    rate = 1.0 / float(t[1] - t[0])
    pitch = foot_pitch(heel, toe)
    rate_of_pitch = np.gradient(pitch, 1.0 / rate)  # rad/s, unsmoothed: see _fastest
    guide = derivative(pitch, rate, params.derivative_ms)
    sharp = max(params.off_sharp_ms[int(filtered)] / 1000.0, 1.0 / rate)
    found = []
    for c in coarse:
        lo, hi = c + params.off_window[0] * stride_s, c + params.off_window[1] * stride_s
        i = extremum(t, guide, lo, hi, np.argmin)
        if i is None or i < 0:
            continue
        corner = _fastest(t, rate_of_pitch, i, params)
        corner = corner if np.isfinite(corner) else t[i]
        until = hi + params.off_fit_ms / 1000.0
        rounded = _recovery(t, guide, i, params.off_recovery[0], until) - corner > sharp
        later = _recovery(t, guide, i, params.off_recovery[1], until) if rounded else np.nan
        found.append(later if np.isfinite(later) else corner)
    return found


def noise_mm(tracks: tuple[NDArray, ...]) -> float:
    """Marker noise (mm): the median over ``tracks`` of the robust SD of their third
    differences over sqrt(20) (white noise's gain), NaN where none is known."""
    sds = []
    for x in tracks:
        d3 = np.diff(x, 3, axis=0)
        d3 = d3[np.all(np.isfinite(d3), axis=1)]
        if len(d3):
            sds.append(1.4826 * float(np.median(np.abs(d3))) / np.sqrt(20.0))
    return float(np.median(sds)) if sds else float("nan")


def _recovery(t: NDArray, y: NDArray, i: int, fraction: float, until: float) -> float:
    """First time after sample ``i`` (a minimum) where ``y`` has come back ``fraction``
    of the way from ``y[i]`` to 0 (linear interpolation); NaN if not before ``until``."""
    level = y[i] * (1.0 - fraction)
    after = np.flatnonzero((np.arange(len(y)) > i) & (t <= until) & (y >= level))
    if not len(after) or not np.all(np.isfinite(y[i : after[0] + 1])):
        return float("nan")
    k = int(after[0])
    return float(t[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (t[k] - t[k - 1]))


def foot_pitch(heel: NDArray, toe: NDArray) -> NDArray[np.float64]:
    """Pitch of the heel-to-toe line above the horizontal (rad, toe up positive)."""
    d = toe - heel
    return np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))


def _fastest(t: NDArray, rate_of_pitch: NDArray, i: int, params: GaitParams) -> float:
    """Sub-sample time of the end of the push-off near sample ``i``.

    The pitch rate falls slowly through the push-off and turns up sharply once the foot
    is off the floor, so its minimum is a corner; the corner of two quadratics fitted to
    the unsmoothed pitch rate locates it (smoothing, or a parabola through the lowest
    samples, would pull it towards the gentle side by 5-15 ms).
    """
    dt = t[1] - t[0]
    search = max(params.off_search_ms / 1000.0, 2 * dt)
    half = max(params.off_fit_ms / 1000.0, search + 3 * dt, 5 * dt)
    return kink_time(t, rate_of_pitch, t[i], half, search, order=1)


def _coarse(
    markers: GaitMarkers,
    side: str,
    direction: NDArray,
    pelvis_v: NDArray,
    speed: NDArray,
    params: GaitParams,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Zeni's crossings (fractional samples): heel forward -> back, toe back -> forward."""
    rate = markers.rate_hz
    band = params.hysteresis * speed
    out = []
    for marker, sign in ((markers.heel[side], 1.0), (markers.toe[side], -1.0)):
        v = derivative(marker, rate, params.derivative_ms) - pelvis_v
        along = np.sum(v[:, :2] * direction, axis=1)
        hold = max(1, round(params.hold_s * rate))
        out.append(hysteresis_crossings(sign * along, band, -band, hold))
    strikes, offs = out
    # A swing runs from a foot off to one foot strike: of several heel crossings after
    # the same foot off (the heel can lag the pelvis briefly in early swing), the last
    # one ends the swing.
    previous_off = np.searchsorted(offs, strikes)
    last = np.append(previous_off[1:] != previous_off[:-1], True)[: len(strikes)]
    return strikes[last], offs


def foot_direction(
    markers: GaitMarkers, params: GaitParams = DEFAULT_PARAMS
) -> NDArray[np.float64]:
    """Direction the feet point in (n, 2), unit: the horizontal heel-to-toe vectors of
    both feet, summed and smoothed over ``params.direction_s``.

    Toe-out of the two feet cancels in the sum, and a foot points where its owner walks
    whether the ground moves or not, so this is the direction of progression on a
    treadmill too (where the pelvis hardly moves in the lab).
    """
    rate = markers.rate_hz
    parts = []
    for side in SIDES:
        d = (markers.toe[side] - markers.heel[side])[:, :2]
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            parts.append(d / norm)
    with np.errstate(invalid="ignore"), _quiet():
        mean = np.nanmean(np.stack(parts), axis=0)
    flat = smooth(mean, params.direction_s * rate)
    with np.errstate(invalid="ignore", divide="ignore"):
        return flat / np.linalg.norm(flat, axis=1, keepdims=True)


def pelvis_centre(markers: GaitMarkers) -> NDArray[np.float64]:
    """Mean position (n, 3) of the pelvis markers present at each field."""
    with np.errstate(invalid="ignore"), _quiet():
        return np.nanmean(np.stack(markers.pelvis), axis=0)


class _quiet:
    """Silence numpy's 'mean of empty slice' where no pelvis marker is seen."""

    def __enter__(self) -> None:
        import warnings

        self._ctx = warnings.catch_warnings()
        self._ctx.__enter__()
        warnings.simplefilter("ignore", RuntimeWarning)

    def __exit__(self, *exc: object) -> None:
        self._ctx.__exit__(*exc)
