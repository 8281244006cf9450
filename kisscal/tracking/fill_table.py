"""The reach of each way of filling a gap (:data:`~kisscal.tracking.fill_passes.FILLS`): which
runs of missing fields it is tried on, and with which error limit. The fills themselves
and the runner are in :mod:`kisscal.tracking.gaps`; a ``gap`` here is its record,
:class:`~kisscal.tracking.gap_record.Gap` (the track's dense series, the gap's bounds,
parameters and spare blobs).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams


def rest_params(params: TrackingParams) -> TrackingParams:
    """``params`` with the body fill's error limit at most ``ray_rest_max_error_mm`` (for
    fields between ones placed on rays: the body borrows them as its context)."""
    return params.replace(
        max_body_fill_error_mm=min(params.max_body_fill_error_mm, params.ray_rest_max_error_mm)
    )


def enclosed(series: NDArray, a: int, b: int) -> bool:
    """Whether ``series`` (n_fields, 3) has samples just before ``a`` and at ``b``."""
    return 0 < a and b < len(series) and bool(np.all(np.isfinite(series[[a - 1, b]])))


def hole_length(series: NDArray, a: int, b: int) -> int:
    """Fields between the samples of ``series`` (n_fields, 3) beside the run [a, b): the
    hole a spline through them bridges (at least ``b - a``; ``b - a`` at a track's end).
    Fields left between fills not taken as context are part of it (a 60-field hinge's
    hole of one field, spline through the samples beyond it: 96 mm off)."""
    ok = np.flatnonzero(np.isfinite(series[:, 0]))
    i = int(np.searchsorted(ok, a))
    return max(b - a, int(ok[i] - ok[i - 1] - 1) if 0 < i < ok.size else 0)


@dataclass(frozen=True)
class Fill:
    """One way of filling missing fields of a track, and its reach.

    Attributes
    ----------
    name : str
    fill : callable
        ``fill(gap, a, b, params)`` fills what it can of fields [a, b) of ``gap`` (into
        ``gap.out``) and returns the fields it placed, (b - a,) bool.
    sweep : bool
        Tried on every run left by the fills before it, the rest of the list only then
        (otherwise the rest of the list goes on each run it leaves at once).
    rays : bool
        Only with spare blobs, in gaps longer than a spline bridges.
    long_run : bool
        Only on runs longer than a spline bridges (``max_fill_gap_fields``).
    split_only : bool
        Only on the runs left by the fills before it in a run one of them placed part of.
    strict : str
        When the body's error limit is ``ray_rest_max_error_mm``: ``"never"``,
        ``"swept"`` (fields of the gap were placed by a sweeping fill) or ``"always"``.
    ends : bool
        Only at a track's ends (else only in gaps inside it).
    enclosed : bool
        Only on runs with samples (measured or placed) on both sides.
    """

    name: str
    fill: Callable[[Gap, int, int, TrackingParams], NDArray[np.bool_]]
    sweep: bool = False
    rays: bool = False
    long_run: bool = False
    split_only: bool = False
    strict: str = "never"
    ends: bool = False
    enclosed: bool = False

    def reaches(self, gap: Gap, a: int, b: int, split: bool) -> bool:
        """Whether this fill is tried on run [a, b) of ``gap``."""
        long_gap = gap.hi - gap.lo > gap.params.max_fill_gap_fields
        return (
            self.ends == (gap.end != 0)
            and (not self.rays or (gap.spare is not None and long_gap))
            and (not self.long_run or b - a > gap.params.max_fill_gap_fields)
            and (not self.split_only or split)
            and (not self.enclosed or enclosed(gap.dense[gap.t], a, b))
        )

    def params_for(self, gap: Gap) -> TrackingParams:
        """The parameters this fill runs with in ``gap``."""
        if self.strict == "always" or (self.strict == "swept" and gap.swept.any()):
            return rest_params(gap.params)
        return gap.params
