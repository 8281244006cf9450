"""Foot strike instants: where the foot lands, near each coarse (Zeni) strike.

The heel stops descending when it meets the floor; its height turns a corner there
(Hreljac & Marshall 2000), found by a broken-curve fit from where the heel first comes
to rest (Ghoussayni, Stevens, Durham & Ewins 2004); a foot landing flat or on its
forefoot strikes where its tip reaches the floor, if before the heel (Perry 1992): see
:func:`kisscal.gait.detect_events`.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from kisscal.gait.params import GaitParams
from kisscal.gait.signals import first_within, kink_time


def foot_strikes(
    t: NDArray,
    heel: NDArray,
    coarse: NDArray,
    stride_s: float,
    params: GaitParams,
    toe: NDArray | None = None,
) -> tuple[list[float], int]:
    """Foot strikes: the corner of the heel's height near each coarse one, from where
    the heel first reaches its floor (a marker may sink lower in stance; still sinking
    at the end of the window, its lowest is looked for later, :func:`_sunk`). Where the
    heel has no low point there (its height still falls at the end of the window and
    it never came to rest in it, as for a walker whose heel does not land first), the
    coarse event itself (Zeni's rule). Given the ``toe`` marker, from where the heel
    came to rest if it sank on under the load (:func:`_heel_rest`), and a flat or
    forefoot landing strikes where the tip of the foot lands if that comes first
    (:func:`forefoot_landing`). Never before the coarse event: the foot lands after the
    heel has swung furthest forward. Also returns how many came from Zeni's rule
    alone."""
    dt = float(t[1] - t[0])
    half = max(params.strike_fit_ms / 1000.0, 5 * dt)
    search = max(params.strike_search_ms / 1000.0, 2 * dt)
    found = []
    fallback = 0
    for c in coarse:
        lo, hi = c + params.strike_window[0] * stride_s, c + params.strike_window[1] * stride_s
        i = extremum(t, heel[:, 2], lo, hi, np.argmin)
        if i is None:  # a gap or the trial's end after the landing: the part before it,
            # up to where the heel or the toe is lost (the whole foot seen landing)
            seen = heel[:, 2] if toe is None else heel[:, 2] + 0.0 * toe[:, 2]
            i = extremum(t, heel[:, 2], lo, cut_window(t, seen, lo, hi), np.argmin)
            i = None if i == -1 else i  # still falling where the marker is lost
        if i == -1:  # a marker sinking on in stance: its lowest later, its landing here
            i = _sunk(t, heel[:, 2], lo, hi, c + params.strike_sink * stride_s, params)
        if i is not None and i >= 0:  # the corner; failing a clear one, the landing sample
            i = first_within(t, heel[:, 2], lo, i, params.strike_floor_mm)
            if toe is not None:  # came to rest before sinking on (loading, soft tissue)
                i = min(i, _heel_rest(t, heel, toe, lo, i, params))
            # The heel stops descending once on the floor, not while still above it:
            # the corner lies from the field before the landing one on.
            corner = kink_time(t, heel[:, 2], t[i], half, search, earliest=t[i] - dt)
            # Nor before the heel has swung furthest forward (the coarse event): a
            # rounded descent (filtered, low rate) otherwise puts the corner early.
            strike = corner if np.isfinite(corner) else t[i]
            if toe is not None:  # a forefoot (or flat) landing: the toe down first
                strike = np.fmin(strike, forefoot_landing(t, heel, toe, c, stride_s, params))
            found.append(max(strike, float(c)))
        elif i is not None:
            found.append(float(c))
            fallback += 1
    return found, fallback


def forefoot_landing(
    t: NDArray, heel: NDArray, toe: NDArray, c: float, stride_s: float, params: GaitParams
) -> float:
    """Where the tip of the foot reached the floor after the coarse foot strike ``c``:
    sub-field, NaN if not in the strike window (or the window meets an end of the trial
    or a gap).

    Heights are taken above foot flat: the sample of early stance (from the strike
    window's start to ``strike_sink`` of the stride after ``c``) where the heel and toe
    markers are lowest together. The tip lies ``tip_ahead_mm`` ahead of the toe marker
    on the heel-to-toe line, so its height is the toe marker's plus that distance times
    the foot's slope (the toe's height less the heel's, over their distance); the
    landing is where the tip, on its last descent to foot flat from ``tip_floor_mm[1]``
    up, comes within ``tip_floor_mm[0]`` of the floor.

    In a heel-first landing the tip comes down 50-150 ms after the heel; in a flat or
    forefoot landing with it or before it, while the heel marker (or a stand-in behind
    the ankle) still falls (Perry 1992: initial contact by the forefoot or the whole
    foot).
    """
    lo, hi = c + params.strike_window[0] * stride_s, c + params.strike_window[1] * stride_s
    reach = params.strike_sink * stride_s  # back into the swing, on into stance
    sel = np.flatnonzero((t >= c - reach) & (t <= c + reach))  # the swing's may be cut
    if len(sel) < 3 or t[0] >= lo or sel[-1] == len(t) - 1:
        return float("nan")
    h, k = heel[sel], toe[sel]
    if not (np.all(np.isfinite(h)) and np.all(np.isfinite(k))):
        return float("nan")
    stance = np.flatnonzero(t[sel] >= lo)
    flat = int(stance[np.argmin(h[stance, 2] + k[stance, 2])])
    up_heel, up_toe = h[:, 2] - h[flat, 2], k[:, 2] - k[flat, 2]
    tip = up_toe + params.tip_ahead_mm * (up_toe - up_heel) / np.linalg.norm(k - h, axis=1)
    # The tip's last descent to foot flat: from the last sample still tip_floor_mm[1]
    # up (more than noise), the first within tip_floor_mm[0] of the floor.
    up = np.flatnonzero(~(tip[:flat] <= params.tip_floor_mm[1]))
    down = np.flatnonzero(tip[: flat + 1] <= params.tip_floor_mm[0])
    down = down[down > up[-1]] if len(up) else down[:0]
    if not len(down) or not lo <= t[sel[down[0]]] <= hi:
        return float("nan")
    j = int(down[0]) - 1  # the tip falls through tip_floor_mm[0] between j and j + 1
    frac = (tip[j] - params.tip_floor_mm[0]) / (tip[j] - tip[j + 1])
    return float(t[sel[j]] + np.clip(frac, 0.0, 1.0) * (t[sel[j + 1]] - t[sel[j]]))


def _heel_rest(
    t: NDArray, heel: NDArray, toe: NDArray, lo: float, i: int, params: GaitParams
) -> int:
    """The first sample from ``lo`` up to sample ``i`` where the heel marker is at rest:
    it sinks less than ``strike_floor_mm`` over the next ``strike_search_ms`` and lies
    within ``heel_down_mm`` of ``heel[i]``, once the foot has stopped turning its toes
    up (past its highest pitch: in terminal swing a heel can hover above the floor while
    the toes still rise); ``i`` if none.

    A heel marker may come to rest on landing and sink a few mm more under the loading
    that follows, its height lowest 50-70 ms late (Ghoussayni et al. 2004 time heel
    contact where the heel marker comes to rest).
    """
    sel = np.flatnonzero((t >= lo) & (np.arange(len(t)) <= i))
    d = toe[sel] - heel[sel]
    if not np.all(np.isfinite(d)):
        return i
    sel = sel[int(np.argmax(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))) :]
    z = heel[:, 2]
    w = max(2, round(params.strike_search_ms / 1000.0 / float(t[1] - t[0])))
    ahead = sliding_window_view(np.append(z, np.full(w, np.inf)), w + 1)[sel].min(axis=1)
    rest = sel[(z[sel] <= ahead + params.strike_floor_mm) & (z[sel] <= z[i] + params.heel_down_mm)]
    return int(rest[0]) if len(rest) else i


def _sunk(t: NDArray, z: NDArray, lo: float, hi: float, until: float, params: GaitParams) -> int:
    """Where a heel marker that sinks on through stance (its lowest up to ``until``)
    landed: the first sample by ``hi`` within ``strike_floor_mm`` of its lowest over
    the next ``strike_search_ms`` and within ``heel_down_mm`` of its lowest; -1 if none."""
    i = extremum(t, z, lo, until, np.argmin)
    if i is None or i < 0:
        return -1
    w = max(2, round(params.strike_search_ms / 1000.0 / float(t[1] - t[0])))
    for j in np.flatnonzero((t >= lo) & (t <= hi)):
        ahead = np.nanmin(z[j : j + w])
        if z[j] <= ahead + params.strike_floor_mm and z[j] <= z[i] + params.heel_down_mm:
            return int(j)
    return -1


def cut_window(t: NDArray, y: NDArray, lo: float, hi: float) -> float:
    """``hi``, or, where a gap or the trial's end cuts the window [``lo``, ``hi``] after
    a valid start, the time of the last valid sample but one before the cut (the
    window then ends inside the data, as :func:`extremum` asks)."""
    sel = np.flatnonzero((t >= lo) & (t <= hi))
    lost = np.flatnonzero(~np.isfinite(y[sel]))
    end = sel[lost[0]] if len(lost) else (len(t) if len(sel) and sel[-1] == len(t) - 1 else 0)
    return float(t[end - 2]) if end >= 2 and len(sel) and end > sel[0] else hi


def extremum(t: NDArray, y: NDArray, lo: float, hi: float, pick) -> int | None:
    """Sample of ``pick`` (argmin / argmax) of ``y`` in [lo, hi]; None where the window
    meets an end of the trial or a gap, -1 where the extremum is at the window's edge
    (no turning point inside)."""
    sel = np.flatnonzero((t >= lo) & (t <= hi))
    if len(sel) < 3 or sel[0] == 0 or sel[-1] == len(t) - 1 or not np.all(np.isfinite(y[sel])):
        return None
    k = int(pick(y[sel]))
    return -1 if k in (0, len(sel) - 1) else int(sel[k])
