"""Stretches of a marker's own measured samples where a fill is tried against
measurement, and the fill's expected error measured on them (:func:`expected_errors`):
a body fill is kept only when it would have found the marker there.

References
----------
Gløersen & Federolf 2016 (gap filling from the other markers of the body, judged on
gaps cut into measured markers).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.fill_donors import across_joint, phase_matched
from kisscal.tracking.params import TrackingParams

#: (target's measured series (n_fields, 3), every track's (n_tracks, n_fields, 3), target
#: index, first gap field, stop field, params) -> filled positions or None.
FillMethod = Callable[..., NDArray[np.float64] | None]


def pseudo_gaps(
    target: NDArray, lo: int, hi: int, margin: int, every: bool = False
) -> list[tuple[int, int]]:
    """Stretches of ``target``'s measured samples, with ``margin`` measured fields on each
    side, where a fill is tried against measurement: two of the gap's length, in the
    measured runs nearest the gap (beside it, or farther in the trial when the runs beside
    it are too short: a shorter stretch, its error scaled up, tells less); failing those,
    the nearest shorter ones (at least 3 fields). With ``every``, all, nearest first, and
    one every half gap's length in each run (for :func:`phase_matched`)."""
    ok = np.all(np.isfinite(target), axis=1)
    padded = np.concatenate([[False], ok, [False]]).astype(np.int8)
    d = np.diff(padded)
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    n = hi - lo
    whole, short = [], []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        room = b - a - 2 * margin
        if room < 3 or (lo < b and a < hi):
            continue
        length = min(n, room)
        # the stretch nearest the gap within the run
        s = (b - margin - length, b - margin) if b <= lo else (a + margin, a + margin + length)
        distance = lo - s[1] if b <= lo else s[0] - hi
        (whole if length == n else short).append((distance, s))
        if every and length == n:
            x = np.arange(a + margin, b - margin - n + 1, max(n // 2, 1))
            far = np.where(b <= lo, lo - x - n, x - hi)
            whole.extend((int(f), (int(y), int(y) + n)) for f, y in zip(far, x, strict=True))
    ranked = sorted(set(whole)) + sorted(short)
    return [s for _, s in (ranked if every else ranked[:2])]


#: Stretches of the motion a fill is tried on (:func:`expected_errors`), nearest the
#: gap's phase first.
SPREAD_STRETCHES = 6


def expected_errors(
    method: FillMethod,
    target: NDArray,
    dense: NDArray,
    exclude: int,
    lo: int,
    hi: int,
    params: TrackingParams,
    centres: NDArray | None = None,
    donors: tuple[int, ...] = (),
    spread: bool = False,
) -> tuple[float, float]:
    """RMS error (mm) of ``method`` on :func:`pseudo_gaps` beside the gap [lo, hi), and
    the RMS of its error along the line of sight of each camera of ``centres`` (n, 3):
    what is left once a single camera's ray fixes the other two coordinates
    (:mod:`kisscal.tracking.rayfill`; NaN without ``centres``); with one or two
    ``donors``, on stretches in the gap's phase of the motion (:func:`phase_matched`):
    the first two it can be made on, or with ``spread`` all of the first
    :data:`SPREAD_STRETCHES` (its spread over that phase, not two samples of it). With
    donors across a joint (:func:`~.fill_donors.across_joint`), the larger of the
    errors in the joint's phase and beside the gap, and NaN when none can be made beside
    it: the joint's phase alone passed an end fill that nothing beside the gap checked
    (lowcost 432: a toe carried through the shank at the trial's end, 2.1 mm expected,
    31 mm off)."""
    sd = params.rigid_fill_sd_mm
    split = across_joint(target, dense, donors, sd)
    margin = params.body_context_fields // 2
    spans = pseudo_gaps(target, lo, hi, margin, 1 <= len(donors) <= 2 or bool(split[1]))
    tried = phase_matched(spans, target, dense, donors, (lo, hi), sd, split)

    def made(cut: NDArray, plo: int, phi: int) -> tuple[NDArray, tuple[int, ...]] | None:
        return method(cut, dense, exclude, plo, phi, params)

    got = _errors_on(made, target, hi - lo, centres, tried[:SPREAD_STRETCHES], spread)
    if not split[1]:
        return got
    nearest = [(s, 1.0) for s in pseudo_gaps(target, lo, hi, margin)]
    beside = _errors_on(made, target, hi - lo, centres, nearest, False)
    # NaN beside the gap stays NaN (nothing to check the fill by: not made, as before)
    whole, along = (
        b if np.isnan(g) else float(np.maximum(g, b)) for g, b in zip(got, beside, strict=True)
    )
    return whole, along


def _errors_on(
    made: Callable[[NDArray, int, int], tuple[NDArray, tuple[int, ...]] | None],
    target: NDArray,
    n_gap: int,
    centres: NDArray | None,
    tried: list[tuple[tuple[int, int], float]],
    spread: bool,
) -> tuple[float, float]:
    """:func:`expected_errors` of a gap of ``n_gap`` fields on the stretches ``tried``
    (each with its scale), the fill ``made(cut target, lo, hi)`` on each."""
    err, along = [], []
    for (plo, phi), turn in tried:
        cut = target.copy()
        cut[plo:phi] = np.nan
        enough = len(err) == 2 and not spread
        got = None if enough else made(cut, plo, phi)
        if got is None:
            continue
        # a stretch shorter than the gap tells less: a fill's error grows about with the
        # square of the time it bridges (a drift that accelerates), so scale it up so
        scale = (n_gap / (phi - plo)) ** 2 * turn
        miss = got[0] - target[plo:phi]
        err.append(np.sqrt(np.mean(np.sum(miss**2, axis=1))) * scale)
        if centres is not None:
            sight = target[plo:phi][None] - centres[:, None]
            sight /= np.linalg.norm(sight, axis=2, keepdims=True)
            along.append(np.sqrt(np.mean(np.einsum("cnj,nj->cn", sight, miss) ** 2)) * scale)
    rms = [float(np.sqrt(np.mean(np.square(e)))) if e else float("nan") for e in (err, along)]
    return rms[0], rms[1]
