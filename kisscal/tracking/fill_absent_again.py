"""A name placed too short to be named, or nowhere, tried again once every gap is filled.

:func:`~kisscal.tracking.fill_absent.absent_rows` places the names no track took on
their blobs' rays before the gaps are filled; a name placed in fewer than
``min_track_length`` fields is left unnamed there. Once every gap is filled, its
partners' ray fills are context too, and it is placed again with them
(:func:`absent_named`): the cameras that miss a knee mostly miss its tibia and ankle
too. A name a track holds, measured in too few fields to learn its own lengths
(:func:`~kisscal.tracking.fill_absent.thin_names`), fills that track where it is
neither measured nor filled.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera); Challis 1995 (segments as rigid
bodies of markers).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_absent import absent_placed, absent_tracks, ray_runs
from kisscal.tracking.fill_trusted import context
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs


@dataclass(frozen=True)
class AbsentContext:
    """What the names :func:`absent_placed` left unnamed are tried again with, once every
    gap is filled (:func:`absent_named`).

    Attributes
    ----------
    dense : (n_tracks, n_fields, 3) float array
        The tracks' samples (read where ``measured``).
    measured : (n_tracks, n_fields) bool array
        The tracks' measured samples.
    made : sequence of (xyz, GapFill)
        The fills made; their ray fills are trusted as context
        (:func:`~kisscal.tracking.fill_trusted.context`).
    labels : sequence of str or None
        One name per track.
    placed : (who, rows, sds)
        :func:`~.fill_absent.absent_rows`'s result: each placed name and its partners, its row
        (m, n_fields, 3) and each field's expected error (m, n_fields).
    missing : sequence of str
        The set's names no track took.
    spare : SpareBlobs or None
        The blobs no 3D point used (None: none is tried again).
    params : TrackingParams
    """

    dense: NDArray[np.float64]
    measured: NDArray[np.bool_]
    made: Sequence[tuple[NDArray, GapFill]]
    labels: Sequence[str] | None
    placed: tuple[list[tuple[str, NDArray[np.int64]]], NDArray, NDArray]
    missing: Sequence[str]
    spare: SpareBlobs | None
    params: TrackingParams


def absent_named(ctx: AbsentContext) -> tuple[list[str], list[tuple[NDArray, GapFill]]]:
    """:func:`absent_tracks` of :func:`absent_placed`'s result (``ctx.placed``), the names
    it left unnamed (placed in fewer than ``min_track_length`` fields, or nowhere) tried
    again once every gap is filled: with the tracks' measured samples and their ray fills
    of ``ctx.made`` trusted as context (``filled_rigid``, expecting at most
    ``ray_rest_max_error_mm``; that error is added to the lengths' SDs). The cameras that
    miss a knee mostly miss its tibia and ankle too: kiss 3 seed 414's were measured
    together in 23 fields and placed on one camera's rays in 226, so the knee, which one
    camera sees throughout, was placed in 4 fields and left unnamed. A name tried again
    keeps the fields placed before (their blobs taken)."""
    n = len(ctx.dense)
    who, rows, sds = _again(ctx)
    own = {name: t for t, name in enumerate((ctx.labels or ())[:n])}
    new = [k for k, (name, _) in enumerate(who) if name not in own]
    names, out = absent_tracks([who[k] for k in new], rows[new], sds[new], n, ctx.params)
    return names, out + _beside(ctx.measured, ctx.made, who, rows, sds, own)


def _beside(
    measured: NDArray,
    made: Sequence[tuple[NDArray, GapFill]],
    who: list[tuple[str, NDArray[np.int64]]],
    rows: NDArray,
    sds: NDArray,
    own: dict[str, int],
) -> list[tuple[NDArray, GapFill]]:
    """The placed rows of names a track holds (:func:`thin_names`) as fills of that
    track, in the fields where it is neither measured nor filled (``made``)."""
    taken = measured.copy()
    for _, fill in made:
        taken[fill.track, fill.first_field : fill.first_field + fill.n_fields] = True
    out = []
    for (name, partners), row, sd in zip(who, rows, sds, strict=True):
        t = own.get(name)
        if t is None:
            continue
        donors = tuple(partners[partners < len(measured)].tolist())
        out += ray_runs(t, row, sd, np.isfinite(row[:, 0]) & ~taken[t], donors)
    return out


def _again(
    ctx: AbsentContext,
) -> tuple[list[tuple[str, NDArray[np.int64]]], NDArray[np.float64], NDArray[np.float64]]:
    """The names of ``ctx.missing`` placed again (see :func:`absent_named`) with those
    of ``ctx.placed`` kept: every row placed in ``min_track_length`` fields or more, and
    each shorter one whose name was not placed again."""
    dense, measured, made, labels = ctx.dense, ctx.measured, ctx.made, ctx.labels
    placed, missing, spare, params = ctx.placed, ctx.missing, ctx.spare, ctx.params
    who, rows, sds = placed
    long = [
        k for k in range(len(who)) if np.isfinite(rows[k, :, 0]).sum() >= params.min_track_length
    ]
    again = [n for n in missing if n not in {who[k][0] for k in long}]
    if spare is None or not labels or not again:
        return placed
    n = len(dense)
    known = np.where(measured[..., None], dense, np.nan)
    errors = np.where(measured, 0.0, np.nan)
    for xyz, fill in made:
        span = slice(fill.first_field, fill.first_field + fill.n_fields)
        if context(fill, params, trusting=False):  # the second passes' context
            known[fill.track, span] = xyz
            errors[fill.track, span] = fill.expected_error_mm
    known = np.concatenate([known, rows[long]])
    errors = np.concatenate([errors, sds[long]])
    names = [*labels[:n], *(who[k][0] for k in long)]
    new_who, new_rows, new_sds = absent_placed(known, names, again, spare, params, errors)
    if not new_who:
        return placed
    before = {who[k][0]: k for k in range(len(who)) if k not in long}
    for k, (name, _) in enumerate(new_who):  # fields placed before kept
        if name in before:
            old = np.isfinite(rows[before[name], :, 0])
            new_rows[k, old], new_sds[k, old] = rows[before[name], old], sds[before[name], old]
    short = [k for k in before.values() if who[k][0] not in {w[0] for w in new_who}]
    keep = long + short
    return (
        [*(who[k] for k in keep), *new_who],
        np.concatenate([rows[keep], new_rows]),
        np.concatenate([sds[keep], new_sds]),
    )
