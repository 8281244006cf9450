"""Writing a fill's fields: the ones placed on rays taken as context, a body fill moved
onto the rays of blobs a camera still sees (:mod:`kisscal.tracking.gaps`' helpers).

References
----------
Hartley & Zisserman 2004 (rays of a projective camera).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import Candidate, GapFill
from kisscal.tracking.on_rays import ChainFill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs, ray_correct
from kisscal.tracking.segment_lengths import length_partners
from kisscal.tracking.tracks import FILLED_RIGID


def take_placed(
    dense: NDArray, t: int, lo: int, chain: ChainFill, spare: SpareBlobs
) -> list[tuple[NDArray, GapFill]]:
    """The fields ``chain`` placed from ``lo`` on: written into ``dense`` (context for
    the rest), their blobs marked used, one :class:`GapFill` per run."""
    spare.free[chain.rows] = False
    placed = np.isfinite(chain.sd_mm)
    dense[t, lo : lo + placed.size][placed] = chain.xyz_mm[placed]
    out = []
    for a, b in zip(*true_runs(placed), strict=True):
        err = float(np.sqrt(np.mean(chain.sd_mm[a:b] ** 2)))
        donors = tuple(p for p in chain.partners if p < len(dense))  # not placed rows
        fill = GapFill(t, lo + a, b - a, FILLED_RIGID, err, donors, b - a)
        out.append((chain.xyz_mm[a:b], fill))
    return out


def with_rays(
    chosen: Candidate, spare: SpareBlobs, params: TrackingParams
) -> list[tuple[NDArray, GapFill]]:
    """The ``chosen`` fill with its fields moved onto the rays of unused blobs
    (:func:`~kisscal.tracking.rayfill.ray_correct`): one :class:`GapFill` per run of
    fields with and without a ray. A run with rays expects the fill's error along the
    cameras' sight (:func:`~kisscal.tracking.stretches.expected_errors`), or, when larger,
    the one its move onto the rays tells: an error without a preferred direction is
    about 1/sqrt(2) of its part across the sight along it. A run without rays expects
    the fill's error, or, when larger, the whole error the move tells (sqrt(3/2) of its
    part across the sight). Runs where the error the move tells exceeds
    ``max_body_fill_error_mm`` are refused: the rays measured the fill there (modern 3
    seed 306: a heel's end filled expecting 4.8 mm moved 9.5 mm onto its rays, the rayed
    fields kept 7 mm off expecting 6.7, the ones between without a blob 17 mm off
    expecting 4.8).

    Only fills good enough on their own are moved: a fill too poor for a gap is often
    wrong mostly along the one camera's sight, which the ray cannot tell (a pattern fill
    whose along-sight error was expected at 4 mm was 11 mm off on a held-out trial).
    """
    g = chosen.fill
    err = g.expected_error_mm
    sd = err if np.isfinite(err) else params.max_body_fill_error_mm
    xyz, n_rays, used = ray_correct(chosen.xyz_mm, g.first_field, sd, spare, params)
    rayed = n_rays > 0
    told: dict[bool, float] = {}
    if rayed.any():
        # the move's RMS across the sight: the error along one direction, and in all three
        across = np.sqrt(np.mean(np.sum((xyz - chosen.xyz_mm)[rayed] ** 2, axis=1)))
        told = {True: across / np.sqrt(2.0), False: across * np.sqrt(1.5)}
    out = []
    edges = np.flatnonzero(np.r_[True, np.diff(rayed) != 0, True])
    for a, b in zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True):
        fill = dataclasses.replace(g, first_field=g.first_field + a, n_fields=b - a)
        moved = told.get(bool(rayed[a]), np.nan)
        if moved > params.max_body_fill_error_mm:
            continue
        if rayed[a]:
            along = float(np.nanmax([chosen.along_sight_mm, moved]))
            fill = dataclasses.replace(fill, expected_error_mm=along, ray_fields=b - a)
        elif told:
            fill = dataclasses.replace(fill, expected_error_mm=float(np.nanmax([err, moved])))
        out.append((xyz[a:b], fill))
    # a blob whose field is refused stays free for the fills after this one
    kept = placed_mask(out, g.first_field, g.first_field + len(xyz))
    spare.free[used[kept[spare.field[used] - g.first_field]]] = False
    return out


def at_least(fill: GapFill, err: float) -> GapFill:
    """``fill`` expecting at least ``err`` (mm; a NaN leaves it)."""
    return dataclasses.replace(fill, expected_error_mm=float(np.fmax(fill.expected_error_mm, err)))


def placed_mask(
    got: list[tuple[NDArray, GapFill]], a: int, b: int, series: NDArray | None = None
) -> NDArray[np.bool_]:
    """Which fields of [a, b) the fills ``got`` ((xyz, fill) pairs) placed; written into
    ``series`` (n_fields, 3) when given."""
    placed = np.zeros(b - a, dtype=bool)
    for xyz, f in got:
        placed[f.first_field - a : f.first_field - a + f.n_fields] = True
        if series is not None:
            series[f.first_field : f.first_field + f.n_fields] = xyz
    return placed


def mirror_checked(
    dense: NDArray, t: int, params: TrackingParams, mirror: NDArray | None
) -> NDArray:
    """``dense`` without the tracks whose length to track ``t`` holds over the trial while
    their mirror pair's does not over the same fields
    (:func:`~kisscal.tracking.segment_lengths.length_partners`): the body must not carry a marker
    by a length held in one phase of gait alone (modern 3 seed 353: RANK carried by RTHI,
    held only in RTHI's stance, 7.9 mm off expecting 1.8)."""
    if mirror is None:
        return dense
    drop = np.setdiff1d(
        length_partners(dense, t, params)[0], length_partners(dense, t, params, mirror)[0]
    )
    if drop.size == 0:
        return dense
    out = dense.copy()
    out[drop] = np.nan
    return out
