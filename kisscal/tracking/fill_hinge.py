"""Gap fill of a marker whose segment's two other markers are measured: its turn about
their axis carried across the gap by a cubic.

A foot (heel, ankle, toe) or a shank (knee, tibia, ankle) carries three markers. With one
hidden and the two others measured through the gap, the hidden one lies on a circle about
their axis: its place along the axis and its distance from it hold (the segment is
rigid), and only its angle about the axis is unknown. Rigid-body fill needs a third
carrier to fix that angle, and a marker across a joint (the tibia for a heel) moves it
wrong; the two-marker fill (:func:`~kisscal.tracking.bodyfill.axis_fill`) holds the
angle against a lab direction, which a foot rolling through stance and swing does not.
Here the angle, measured against the lab direction the axis comes least near in the
trial (:func:`~kisscal.tracking.fill_donors.lab_reference`; the frame of
:func:`~kisscal.tracking.fill_donors.axis_frames`), is carried across the gap by a cubic
in time fitted by least squares to up to ``fill_context_fields`` samples on each side
(:data:`DEGREE`; an interpolating spline through them passed their noise on: 5 mm RMS
against 0.7 on a 0.3 s gap with 0.3 mm noise); the place along the axis and the distance
from it drift linearly from each side's mean to the other's.

Its expected error is measured as for the other body fills
(:func:`~kisscal.tracking.stretches.expected_errors`, on stretches of the marker's own
measured samples), which refuses it where the angle turns too fast for the cubic.

References
----------
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (gap
filling from the other markers of the body).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import (
    AXIS_MAX_COS,
    BODY_METHODS,
    axis_frames,
    distance_sd,
    ramp,
    rigid_pair,
    side_windows,
)
from kisscal.tracking.fill_donors import lab_reference
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import FILLED_RIGID

#: Degree of the polynomial the angle is carried across the gap by, fitted by least
#: squares to the samples of both sides (an interpolating spline through them passes on
#: their noise, magnified by the gap's length).
DEGREE = 3

#: :func:`neighbour_hinge_fill`: largest cosine between the pair's axis and the third
#: marker's direction. Unlike the lab's (:data:`AXIS_MAX_COS`), that direction turns
#: with the body; it only has to keep a part square to the axis to count the angle from
#: (at 0.9, 0.44 of its length: a shank marker 0.3 mm off turns a heel's angle by
#: about 0.3 mm at the heel).
NEIGHBOUR_MAX_COS = 0.9


def _pair(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> NDArray[np.int64] | None:
    """The two markers measured through the gap [lo, hi) that keep their distances to
    ``target`` and to each other best, within ``rigid_fill_sd_mm`` SD over the trial
    (None without two)."""
    through = np.all(np.isfinite(dense[:, lo:hi]), axis=(1, 2))
    through[exclude] = False
    cand = np.flatnonzero(through)
    if cand.size < 2:
        return None
    return rigid_pair(dense, cand, distance_sd(dense[cand], target[None])[:, 0], params)


def _local(target: NDArray, dense: NDArray, pair: NDArray, f: NDArray, ref: NDArray) -> NDArray:
    """``target`` at fields ``f`` in the frame of ``pair`` (:func:`axis_frames`): along
    the axis, distance from it, angle about it (rad), (len(f), 3)."""
    r = axis_frames(dense[pair[0], f], dense[pair[1], f], ref)
    here = np.einsum("nji,nj->ni", r, target[f] - dense[pair[0], f])
    return np.c_[here[:, 0], np.hypot(here[:, 1], here[:, 2]), np.arctan2(here[:, 2], here[:, 1])]


def _bridge(f: NDArray, value: NDArray, lo: int, hi: int) -> NDArray[np.float64]:
    """``value`` at fields ``f`` (both sides of the gap [lo, hi)) carried across the gap:
    the cubic fitted by least squares (a line through two samples), centred on the gap
    (the fit's conditioning)."""
    mid = 0.5 * (lo + hi - 1)
    coef = np.polynomial.polynomial.polyfit(f - mid, value, min(DEGREE, f.size - 2))
    return np.polynomial.polynomial.polyval(np.arange(lo, hi) - mid, coef)


def _third(
    target: NDArray, dense: NDArray, exclude: int, pair: NDArray, lo: int, hi: int
) -> int | None:
    """The marker measured through the gap [lo, hi), other than ``pair`` and
    ``exclude``, whose distance to ``target`` varies least over the trial (the
    neighbouring segment's: a shank marker for a foot's), or None."""
    through = np.all(np.isfinite(dense[:, lo:hi]), axis=(1, 2))
    through[[exclude, *pair.tolist()]] = False
    cand = np.flatnonzero(through)
    if not cand.size:
        return None
    sd = distance_sd(dense[cand], target[None])[:, 0]
    return int(cand[np.argmin(sd)]) if np.isfinite(sd).any() else None


def _hinge(
    target: NDArray,
    dense: NDArray,
    pair: NDArray,
    ref: NDArray | None,
    lo: int,
    hi: int,
    params: TrackingParams,
    max_cos: float = AXIS_MAX_COS,
) -> NDArray[np.float64] | None:
    """Fields [lo, hi) of ``target`` about the axis of ``pair``, its angle measured from
    ``ref`` (n_fields, 3: the direction the angle is counted from; None: the lab axis
    the pair's axis comes least near in the trial, :func:`lab_reference`) carried by
    :func:`_bridge`; None with fewer than two samples of all on a side, or where the
    axis turns within ``acos(max_cos)`` of ``ref``."""
    both = np.all(np.isfinite(dense[pair]), axis=(0, 2))
    if ref is not None:
        both &= np.all(np.isfinite(ref), axis=1)
    seen = np.where(both[:, None], target, np.nan)
    before, after = side_windows(seen, lo, hi, params.fill_context_fields)
    if before.size < 2 or after.size < 2:
        return None
    f = np.r_[before, after]
    span = np.arange(before[0], after[-1] + 1)
    axis = dense[pair[1], span] - dense[pair[0], span]
    if ref is None:  # the trial's, not the span's: expected_errors' stretches share it
        lab = lab_reference(dense[pair[1]] - dense[pair[0]])
        ref = np.broadcast_to(lab, target.shape)
    cos = np.sum(axis * ref[span], axis=1)
    cos /= np.linalg.norm(axis, axis=1) * np.linalg.norm(ref[span], axis=1)
    if np.nanmax(np.abs(cos)) > max_cos:
        return None  # the axis turns towards the reference: the angle is lost
    local = _local(target, dense, pair, f, ref[f])
    angle = np.unwrap(local[:, 2])
    theta = _bridge(f, angle, lo, hi)
    w = ramp(lo, hi)
    nb = before.size
    x, rad = (local[:nb, i].mean() * (1 - w) + local[nb:, i].mean() * w for i in (0, 1))
    r = axis_frames(dense[pair[0], lo:hi], dense[pair[1], lo:hi], ref[lo:hi])
    here = np.c_[x, rad * np.cos(theta), rad * np.sin(theta)]
    return np.einsum("nij,nj->ni", r, here) + dense[pair[0], lo:hi]


def hinge_fill(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
    """Fill fields [lo, hi) of ``target`` (n_fields, 3; NaN where not measured) about
    the axis of the two markers of its segment measured through the gap (see module),
    its angle counted from the lab direction the axis comes least near in the trial
    (the same for the gap and the stretches its error is measured on); None without two
    such markers, with fewer than two samples of all three on a side, or where the
    axis turns within ``acos(AXIS_MAX_COS)`` of the lab direction."""
    pair = _pair(target, dense, exclude, lo, hi, params)
    if pair is None:
        return None
    got = _hinge(target, dense, pair, None, lo, hi, params)
    return None if got is None else (got, tuple(int(p) for p in pair))


def neighbour_hinge_fill(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
    """:func:`hinge_fill` with the angle counted from a third marker's direction
    (:func:`_third`, the neighbouring segment's) instead of the lab's: a foot's turn
    about its ankle-toe axis follows the shank's swing more than the lab (on the
    synthetic walk a cubic carries the heel's angle 11 fields at 30 Hz to 1.4 mm RMS
    from the shank, 5.1 from the lab). Donors: the pair and the third."""
    pair = _pair(target, dense, exclude, lo, hi, params)
    if pair is None:
        return None
    third = _third(target, dense, exclude, pair, lo, hi)
    if third is None:
        return None
    ref = dense[third] - dense[pair[0]]
    got = _hinge(target, dense, pair, ref, lo, hi, params, NEIGHBOUR_MAX_COS)
    return None if got is None else (got, (*(int(p) for p in pair), third))


#: The body's fills of a gap longer than a spline bridges
#: (:data:`~kisscal.tracking.bodyfill.BODY_METHODS`), :func:`hinge_fill` and
#: :func:`neighbour_hinge_fill`.
HINGE_METHODS = (
    *BODY_METHODS,
    (FILLED_RIGID, hinge_fill),
    (FILLED_RIGID, neighbour_hinge_fill),
)
