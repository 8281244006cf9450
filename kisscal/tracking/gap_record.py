"""The record of one gap of a track being filled: what every fill of
:data:`~kisscal.tracking.fill_passes.FILLS` reads, and where it writes what it places.

Built once per run of missing fields by the runner (:mod:`kisscal.tracking.fill_runner`) and
handed to each fill in turn. Its fields are fixed; the arrays and list it carries are
not: the fills write placed fields into ``dense`` (context for the fills after them),
their expected errors into ``errors``, the fields the sweeping fills placed into
``swept`` and the fills made into ``out``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs


@dataclass(frozen=True)
class Gap:
    """One gap [lo, hi) of track ``t`` being filled.

    Attributes
    ----------
    dense : (n_tracks, n_fields, 3) float array
        Every track's samples (NaN where none), fills written in as context.
    t, lo, hi : int
        The track and the gap's fields [lo, hi).
    params : TrackingParams
    spare : SpareBlobs or None
        The blobs no 3D point used (None: no fill on rays).
    measured : (n_fields,) bool array or None
        The track's measured fields (for the depth fill's spline).
    swept : (hi - lo,) bool array
        The fields placed by the sweeping fills.
    out : list of (xyz, GapFill)
        The fills made.
    end : int
        0 for a gap inside the track, -1 for the fields before its first measured
        sample, 1 after its last.
    absent : (m, n_fields, 3) float array or None
        Rows of markers no track took (:mod:`.fill_absent`), for the joint fills.
    known : (n_tracks, n_fields) bool array or None
        Every track's measured samples (the second passes': the sphere fill counts a
        placed partner's error).
    expected : (n_tracks, n_fields) float array or None
        The error of each track's known samples, NaN where none (the last pass's,
        :mod:`.fill_unmerged`).
    errors : (n_tracks + m, n_fields) float array or None
        Every sample's expected error (0 measured, a fill's as it is made, the
        ``absent`` rows' along their rays; NaN where none), for the chain fill's placed
        partners.
    mirror : int array or None
        Each row's mirror image's row, -1 for none (:func:`.fill_absent.mirror_tracks`).
    borrowed : (n_tracks, n_fields) bool array or None
        The trusted pass's: samples written into ``dense`` as its context that the passes
        before it did not have (:func:`~.fill_trusted.context`), so no body fill through
        them was tried there.
    """

    dense: NDArray[np.float64]
    t: int
    lo: int
    hi: int
    params: TrackingParams
    spare: SpareBlobs | None
    measured: NDArray[np.bool_] | None
    swept: NDArray[np.bool_]
    out: list[tuple[NDArray[np.float64], GapFill]]
    end: int = 0
    absent: NDArray[np.float64] | None = None
    known: NDArray[np.bool_] | None = None
    expected: NDArray[np.float64] | None = None
    errors: NDArray[np.float64] | None = None
    mirror: NDArray[np.int64] | None = None
    borrowed: NDArray[np.bool_] | None = None
