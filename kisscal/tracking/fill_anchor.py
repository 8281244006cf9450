"""A fill read off placed fields expects at least their error.

A gap's fills are made one after another, the fields each places becoming context for
the ones after it (:mod:`kisscal.tracking.gaps`). A spline or body fill between such
fields is tried on stretches of the marker's samples beside it
(:func:`~kisscal.tracking.stretches.expected_errors`), which tells how well it follows
those samples, not how far they lie from the marker: where they are themselves fills,
their own error carries into it (modern 3 cameras seed 301: a knee's two-field spline
between fields placed on one camera's rays 3 mm off, 5.5 mm off expecting 0.64).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_place import mirror_checked
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams


def anchored(
    got: list[tuple[NDArray, GapFill]],
    made: Sequence[tuple[NDArray, GapFill]],
    context: int,
) -> list[tuple[NDArray, GapFill]]:
    """The fills ``got`` (xyz, fill) pairs, each expecting at least the largest expected
    error of the fills ``made`` before it in its track within ``context`` fields of
    either side (the samples it was read off).

    Parameters
    ----------
    got : list of (ndarray, GapFill)
        New fills of one track.
    made : sequence of (ndarray, GapFill)
        The fills placed before them (context for them).
    context : int
        Fields on each side a fill reads (``fill_context_fields``).

    Returns
    -------
    list of (ndarray, GapFill)
    """
    out = []
    for xyz, fill in got:
        lo, hi = fill.first_field - context, fill.first_field + fill.n_fields + context
        near = [
            f.expected_error_mm
            for _, f in made
            if f.track == fill.track and f.first_field < hi and lo < f.first_field + f.n_fields
        ]
        floor = np.nanmax(near) if near and np.isfinite(near).any() else np.nan
        if floor > fill.expected_error_mm:  # False with NaN on either side
            fill = dataclasses.replace(fill, expected_error_mm=float(floor))
        out.append((xyz, fill))
    return out


def donor_noise(
    got: list[tuple[NDArray, GapFill]], dense: NDArray
) -> list[tuple[NDArray, GapFill]]:
    """The fills ``got`` (xyz, fill) pairs, each expecting at least the noise of its
    donors (rows of ``dense``, (n_tracks, n_fields, 3)) over its fields: the RMS of their
    second differences over sqrt(6) (white noise; a walk's acceleration adds little at
    a capture's rate). The stretches a fill is tried on may have quieter donors than its
    gap (lowcost seed 362: a sacrum from two hip markers seen by two cameras, 1-4.6 mm
    off, filled 2.7 mm RMS off expecting 1.0, as on stretches where three saw them)."""
    out = []
    for xyz, fill in got:
        rows = dense[list(fill.donors), fill.first_field : fill.first_field + fill.n_fields]
        acc = np.sum(np.diff(rows, 2, axis=1) ** 2, axis=2)
        acc = acc[np.isfinite(acc)]
        if fill.donors and acc.size:
            floor = float(np.sqrt(np.mean(acc) / 6.0))
            fill = dataclasses.replace(
                fill, expected_error_mm=float(np.fmax(fill.expected_error_mm, floor))
            )
        out.append((xyz, fill))
    return out


def trusted(dense: NDArray, errors: NDArray | None, t: int, limit: float) -> NDArray:
    """``dense`` (n_tracks, n_fields, 3) without the samples of tracks other than ``t``
    whose expected error (``errors``, (>= n_tracks, n_fields), NaN where none) is over
    ``limit``: a body fill's error is measured beside its gap, where its donors are
    measured, and a donor that is a poor fill in the gap carries it off unseen (kiss 3
    seed 412: RANK carried by RTOE, a chain fill 15 mm off expecting 4.0, 12 mm off
    expecting 1.3)."""
    if errors is None:
        return dense
    with np.errstate(invalid="ignore"):
        drop = errors[: len(dense)] > limit
    drop[t] = False
    if not drop.any():
        return dense
    out = dense.copy()
    out[drop] = np.nan
    return out


def donor_errors(
    got: list[tuple[NDArray, GapFill]], errors: NDArray | None
) -> list[tuple[NDArray, GapFill]]:
    """The fills ``got`` (xyz, fill) pairs, each expecting at least the largest expected
    error (``errors``, NaN where none) of its donors' samples over its fields: a donor
    that is itself a fill there carries its error into the fill."""
    out = []
    for xyz, fill in got:
        if errors is not None and fill.donors:
            rows = errors[list(fill.donors), fill.first_field : fill.first_field + fill.n_fields]
            if np.isfinite(rows).any():
                err = float(np.fmax(fill.expected_error_mm, np.nanmax(rows)))
                fill = dataclasses.replace(fill, expected_error_mm=err)
        out.append((xyz, fill))
    return out


def body_donors(gap: Gap, params: TrackingParams) -> NDArray:
    """The samples a body fill of ``gap`` (a :class:`~kisscal.tracking.gap_record.Gap`) may
    follow: :func:`~.fill_place.mirror_checked`'s, without other tracks' fills expecting
    more than ``ray_rest_max_error_mm`` (:func:`trusted`; the bar of a fill taken as
    context, :func:`~kisscal.tracking.fill_runner.second_pass`)."""
    body = mirror_checked(gap.dense, gap.t, params, gap.mirror)
    return trusted(body, gap.errors, gap.t, params.ray_rest_max_error_mm)
