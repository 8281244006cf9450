"""A fill read off placed fields expects at least their error.

A gap's fills are made one after another, the fields each places becoming context for
the ones after it (:mod:`kisscal.tracking.gaps`). A spline or body fill between such
fields is tried on stretches of the marker's samples beside it
(:func:`~kisscal.tracking.bodyfill.expected_errors`), which tells how well it follows
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
