"""Fields of a gap placed on the rays of a marker's blobs: the record every single-camera
fill returns (:class:`ChainFill`), kept in runs of at least :data:`MIN_RUN` fields.

A field alone on a ray is as likely a stray blob's as the marker's; a run of them is a
path (:func:`path_runs`). The fills that place such runs: :mod:`kisscal.tracking.raychain`
(the segment's lengths), :mod:`kisscal.tracking.fill_joint` (with the segment's other
markers on theirs), :mod:`kisscal.tracking.fill_depth` and
:mod:`kisscal.tracking.fill_sphere` (a depth fitted across the gap) and those after them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs

#: Fewest consecutive fields placed on rays for them to be kept.
MIN_RUN = 2


def path_runs(placed: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The fields of ``placed`` in runs of at least :data:`MIN_RUN`: a path, not a
    stray field."""
    out = np.zeros(placed.shape, dtype=bool)
    for a, b in zip(*true_runs(placed), strict=True):
        out[a:b] = b - a >= MIN_RUN
    return out


@dataclass(frozen=True)
class ChainFill:
    """A gap's fields placed on the rays of the marker's own blobs.

    Attributes
    ----------
    xyz_mm : (n, 3) float array
        Position per gap field (NaN where none was placed).
    sd_mm : (n,) float array
        Expected error per field (NaN where none was placed).
    partners : tuple of int
        Tracks whose distances fixed the depth.
    rows : int array
        Rows of the spare blobs taken.
    """

    xyz_mm: NDArray[np.float64]
    sd_mm: NDArray[np.float64]
    partners: tuple[int, ...]
    rows: NDArray[np.int64]
