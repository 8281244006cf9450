"""The runner of a pass of gap fills: each run of a gap's missing fields tried by a
pass's fills in turn (:data:`~kisscal.tracking.fill_passes.FILLS` and the passes after
it), each fill on what the ones before it left, within its reach
(:class:`~kisscal.tracking.fill_table.Fill`); the fields placed become context for the
fills after them. :func:`fill_runs` runs the first pass and the track ends,
:func:`second_pass` the passes after them on what was left.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_table import Fill
from kisscal.tracking.fill_trusted import context
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs


def _left(a: int, placed: NDArray) -> list[tuple[int, int]]:
    """The runs of fields from ``a`` that ``placed`` leaves."""
    lo, hi = true_runs(~placed)
    return [(a + x, a + y) for x, y in zip(lo.tolist(), hi.tolist(), strict=True)]


def _note(gap: Gap, made: int) -> None:
    """The expected error of the fills of ``gap.out`` from ``made`` on into
    ``gap.errors`` (read only where a fill's fields are in ``gap.dense``)."""
    for _, fill in gap.out[made:] if gap.errors is not None else ():
        gap.errors[fill.track, fill.first_field : fill.first_field + fill.n_fields] = (
            fill.expected_error_mm
        )


def _apply(
    gap: Gap, fills: tuple[Fill, ...], runs: list[tuple[int, int]], split: bool = False
) -> None:
    """Try ``fills[0]`` on each run of ``runs`` in its reach, the rest of ``fills`` on
    what it leaves (after all runs when it sweeps, run by run otherwise)."""
    if not fills or not runs:
        return
    head, tail = fills[0], fills[1:]
    left: list[tuple[int, int]] = []
    for a, b in runs:
        if not head.reaches(gap, a, b, split):
            got = [(a, b)]
            placed = False
        else:
            made = len(gap.out)
            mask = head.fill(gap, a, b, head.params_for(gap))
            _note(gap, made)
            got, placed = _left(a, mask), bool(mask.any())
            if head.sweep:
                gap.swept[a - gap.lo : b - gap.lo] |= mask
        if head.sweep:
            left.extend(got)
        else:
            _apply(gap, tail, got, placed or split)
    if head.sweep:
        _apply(gap, tail, left)


def fill_runs(
    dense: NDArray,
    runs: Iterable[tuple[int, int, int, int]],
    params: TrackingParams,
    spare: SpareBlobs | None,
    measured: NDArray,
    absent: NDArray | None,
    fills: tuple[Fill, ...],
    errors: NDArray | None = None,
    mirror: NDArray | None = None,
) -> list[tuple[NDArray, GapFill]]:
    """Each run (track, lo, hi, end) filled by ``fills`` (:data:`~.fill_passes.FILLS`)
    in turn; placed fields become context (in ``dense``) for the rest. ``measured``:
    every track's measured fields; ``end``, ``absent`` and ``errors``: see
    :class:`~.gap_record.Gap`."""
    out = []
    for t, lo, hi, end in runs:
        swept = np.zeros(hi - lo, bool)
        gap = Gap(
            dense,
            t,
            lo,
            hi,
            params,
            spare,
            measured[t],
            swept,
            [],
            end,
            absent=absent,
            errors=errors,
            mirror=mirror,
        )
        _apply(gap, fills, [(lo, hi)])
        out += gap.out
    return out


def second_pass(
    dense: NDArray,
    gaps: list[tuple[int, int, int]],
    params: TrackingParams,
    spare: SpareBlobs | None,
    measured: NDArray,
    made: Iterable[tuple[NDArray, GapFill]],
    absent: NDArray | None,
    fills: tuple[Fill, ...],
    errors: NDArray | None = None,
    mirror: NDArray | None = None,
    trusting: bool = False,
) -> list[tuple[NDArray, GapFill]]:
    """The fields of ``gaps`` (track, lo, hi) the first pass left (its fills ``made``,
    (xyz, fill) pairs), filled again by ``fills`` (:data:`~.fill_passes.SECOND_PASS`, or
    after the ends :data:`~.fill_passes.LAST_PASS`, then
    :data:`~.fill_trusted.TRUSTED_PASS`), with its rigid and ray fills expecting at most
    ``ray_rest_max_error_mm`` (:func:`~.fill_trusted.context`) written into ``dense`` as
    context (for these fills and the track ends after them); ``trusting`` for the trusted
    pass, whose fills count their donors' errors and know which of their context samples
    the passes before had not (``Gap.borrowed``).

    Tracks are filled one after another, so a marker's gap is filled before its
    segment's partner's gap in the same fields is: a toe seen by one camera while the
    heel, seen by another one, waits its turn has no partner to be placed by. Once the
    heel is placed, its length holds the toe on its ray as a measured heel's would.
    Spline and pattern fills are not context (one through a partner's wrong samples
    would carry the marker onto them; on rays, the trusted pass's), nor does the body
    expect over ``ray_rest_max_error_mm`` here (with the new context: 12 mm off expecting 4).
    """
    if spare is None:
        return []
    done = np.isfinite(dense[:, :, 0])
    expected = np.where(measured, 0.0, np.nan)
    borrowed = np.zeros(done.shape, dtype=bool)
    for xyz, fill in made:
        span = slice(fill.first_field, fill.first_field + fill.n_fields)
        done[fill.track, span] = True
        if context(fill, params, trusting):
            dense[fill.track, span] = xyz
            expected[fill.track, span] = fill.expected_error_mm
            borrowed[fill.track, span] = not context(fill, params, False)
    out = []
    for t, lo, hi in gaps:
        left = ~done[t, lo:hi]
        for a, b in zip(*true_runs(left), strict=True):
            run = (lo + a, lo + b)
            swept = np.zeros(b - a, bool)
            gap = Gap(
                dense,
                t,
                *run,
                params,
                spare,
                measured[t],
                swept,
                [],
                absent=absent,
                known=measured,
                expected=expected,
                errors=errors,
                mirror=mirror,
                borrowed=borrowed if trusting else None,
            )
            _apply(gap, fills, [run])
            out.extend(gap.out)
    return out
