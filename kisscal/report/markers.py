"""What a technician asks of a trial's trajectories: is every marker there, how often,
and do rigid segments keep their length.

Pure functions on a dense (marker x field) layout of ``trajectories.csv``.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.tracking.tracks import LEGACY_STATUS, STATUS_NAMES

#: Codes of :attr:`Dense.status`: the tracker's status codes (``filled`` is the spline
#: fill's name before contract version 3) after :data:`GAP`.
STATUS_CODES = {
    name: code + 1
    for name, code in (*((n, i) for i, n in enumerate(STATUS_NAMES)), *LEGACY_STATUS.items())
}
GAP, MEASURED, PREDICTED, FILLED, FILLED_RIGID, FILLED_PATTERN = 0, 1, 2, 3, 4, 5
#: How a gap was filled, by the Dense code of its samples.
FILL_METHODS = {FILLED: "spline", FILLED_RIGID: "rigid", FILLED_PATTERN: "pattern"}


@dataclass(frozen=True)
class Dense:
    """A trial's trajectories as arrays over (marker, field).

    Attributes
    ----------
    labels : tuple of str
        Trajectory names, in track order.
    xyz_mm : ndarray, shape (n_markers, n_fields, 3)
        Positions (mm); NaN where the trajectory has no sample.
    status : ndarray of int8, shape (n_markers, n_fields)
        :data:`GAP`, :data:`MEASURED`, :data:`PREDICTED`, :data:`FILLED` (spline),
        :data:`FILLED_RIGID` or :data:`FILLED_PATTERN`.
    """

    labels: tuple[str, ...]
    xyz_mm: NDArray[np.float64]
    status: NDArray[np.int8]

    @property
    def n_fields(self) -> int:
        return int(self.status.shape[1])


def dense_trajectories(
    field: ArrayLike, track: ArrayLike, label: ArrayLike, xyz_mm: ArrayLike, status: ArrayLike
) -> Dense:
    """The long table of ``trajectories.csv`` as a :class:`Dense` layout.

    Examples
    --------
    >>> d = dense_trajectories([0, 2, 0], [0, 0, 1], ["A", "A", "B"],
    ...                        [[0, 0, 0], [2, 0, 0], [0, 5, 0]], ["measured"] * 3)
    >>> d.labels, d.status.tolist()
    (('A', 'B'), [[1, 0, 1], [1, 0, 0]])
    """
    field = np.asarray(field, dtype=float).astype(np.int64)
    track = np.asarray(track, dtype=float).astype(np.int64)
    label = np.asarray(label).astype(str)
    xyz = np.asarray(xyz_mm, dtype=float).reshape(-1, 3)
    status = np.asarray(status).astype(str)
    names, first = np.unique(label, return_index=True)
    order = np.lexsort((first, [track[i] for i in first]))
    labels = tuple(str(names[i]) for i in order)
    row = np.argsort(order)[np.searchsorted(names, label)] if len(label) else label
    n_fields = int(field.max()) + 1 if len(field) else 0
    dense = np.full((len(labels), n_fields, 3), np.nan)
    codes = np.zeros((len(labels), n_fields), dtype=np.int8)
    if len(field):
        dense[row, field] = xyz
        codes[row, field] = [STATUS_CODES.get(s, MEASURED) for s in status]
    return Dense(labels, dense, codes)


@dataclass(frozen=True)
class MarkerStats:
    """Presence figures of one trajectory over its trial.

    ``coverage`` is the fraction of the trial's fields with a sample (measured, predicted
    or filled); ``gaps`` counts runs of missing fields between its first and last sample.
    ``coverage_measured`` is the same before filling (measured samples only), and
    ``fills`` says how each filled run was filled: (first field, fields, method) with
    method ``spline``, ``rigid`` or ``pattern``.
    """

    label: str
    coverage: float
    gaps: int
    gap_fields: int
    measured: int
    predicted: int
    filled: int
    coverage_measured: float = 0.0
    filled_rigid: int = 0
    filled_pattern: int = 0
    fills: tuple[tuple[int, int, str], ...] = ()


def filled_runs(status: NDArray[np.int8]) -> tuple[tuple[int, int, str], ...]:
    """(first field, fields, method) of each run of samples filled the same way.

    Examples
    --------
    >>> filled_runs(np.array([1, 3, 3, 1, 4, 4, 4, 5, 1], dtype=np.int8))
    ((1, 2, 'spline'), (4, 3, 'rigid'), (7, 1, 'pattern'))
    """
    code = np.where(status >= FILLED, status, 0).astype(np.int16)
    edge = np.flatnonzero(np.diff(np.concatenate([[0], code, [0]])) != 0).tolist()
    runs = itertools.pairwise(edge)  # each run of one code: [a, b)
    return tuple((a, b - a, FILL_METHODS[int(code[a])]) for a, b in runs if code[a] > 0)


def marker_stats(dense: Dense) -> list[MarkerStats]:
    """Coverage, gaps and sample counts of every trajectory of a trial."""
    present = dense.status != GAP
    n = max(dense.n_fields, 1)
    out = []
    for k, name in enumerate(dense.labels):
        p = present[k]
        idx = np.flatnonzero(p)
        inside = p[idx[0] : idx[-1] + 1] if len(idx) else p[:0]
        starts = np.flatnonzero(np.diff(inside.astype(np.int8)) == -1)  # sample -> gap
        s = dense.status[k]
        out.append(
            MarkerStats(
                label=name,
                coverage=float(p.sum() / n),
                gaps=len(starts),
                gap_fields=int((~inside).sum()),
                measured=int((s == MEASURED).sum()),
                predicted=int((s == PREDICTED).sum()),
                filled=int((s >= FILLED).sum()),
                coverage_measured=float((s == MEASURED).sum() / n),
                filled_rigid=int((s == FILLED_RIGID).sum()),
                filled_pattern=int((s == FILLED_PATTERN).sum()),
                fills=filled_runs(s),
            )
        )
    return out


@dataclass(frozen=True)
class SegmentStats:
    """Length of a rigid segment over a trial, from fields where both ends are measured."""

    a: str
    b: str
    mean_mm: float
    sd_mm: float
    range_mm: float
    samples: int


def segment_lengths(dense: Dense, a: str, b: str) -> NDArray[np.float64]:
    """Distance a-b per field (mm), NaN unless both ends are measured in that field."""
    ia, ib = dense.labels.index(a), dense.labels.index(b)
    both = (dense.status[ia] == MEASURED) & (dense.status[ib] == MEASURED)
    length = np.linalg.norm(dense.xyz_mm[ia] - dense.xyz_mm[ib], axis=1)
    return np.where(both, length, np.nan)


def segment_stats(dense: Dense, segments: Sequence[tuple[str, str]]) -> list[SegmentStats]:
    """Mean, SD and range of the length of each segment whose two ends are trajectories.

    Examples
    --------
    >>> d = dense_trajectories([0, 1, 0, 1], [0, 0, 1, 1], ["A", "A", "B", "B"],
    ...     [[0, 0, 0], [1, 0, 0], [0, 0, 100], [1, 0, 102]], ["measured"] * 4)
    >>> s = segment_stats(d, [("A", "B"), ("A", "C")])
    >>> len(s), s[0].mean_mm, s[0].sd_mm
    (1, 101.0, 1.0)
    """
    out = []
    for a, b in segments:
        if a not in dense.labels or b not in dense.labels:
            continue
        length = segment_lengths(dense, a, b)
        ok = length[np.isfinite(length)]
        if len(ok) == 0:
            continue
        spread = float(ok.max() - ok.min())
        out.append(SegmentStats(a, b, float(ok.mean()), float(ok.std()), spread, len(ok)))
    return out
