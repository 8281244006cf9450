"""Long-format track tables: one row per (track, field) sample."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

MEASURED = 0
PREDICTED = 1
#: Filled by a cubic spline through the measured samples on both sides (short gaps).
FILLED = 2
#: Filled from three or more markers that move rigidly with it (rigid-body fill).
FILLED_RIGID = 3
#: Filled by following a neighbouring marker's motion (pattern fill).
FILLED_PATTERN = 4
#: ``status`` of trajectories.csv for each code (DESIGN.md contract version 3).
STATUS_NAMES = ("measured", "predicted", "filled_spline", "filled_rigid", "filled_pattern")
#: Status names of earlier versions, read as today's code.
LEGACY_STATUS = {"filled": FILLED}


def is_filled(status: NDArray) -> NDArray[np.bool_]:
    """True where a status code (array) says the sample was filled, by any method."""
    return np.asarray(status) >= FILLED


@dataclass(frozen=True)
class Tracks:
    """Track samples, sorted by track then field.

    Attributes
    ----------
    field : (S,) int array
        Field index of each sample.
    track : (S,) int array
        Track number, 0..n_tracks-1 (consecutive).
    xyz_mm : (S, 3) float array
        Position: the measured point, the Kalman prediction or the filled value.
    corrected_mm : (S, 3) float array
        Kalman a-posteriori estimate at that field (NaN where the track had no filter).
    status : (S,) int8 array
        MEASURED, PREDICTED, FILLED (spline), FILLED_RIGID or FILLED_PATTERN.
    point : (S,) int array
        Row of the input point a measured sample came from (-1 otherwise).
    """

    field: NDArray[np.int64]
    track: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    corrected_mm: NDArray[np.float64]
    status: NDArray[np.int8]
    point: NDArray[np.int64]

    @property
    def n_tracks(self) -> int:
        return int(self.track.max()) + 1 if self.track.size else 0

    def bounds(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Row range ``[start[t], stop[t])`` of each track in the sorted table."""
        ids = np.arange(self.n_tracks)
        return (np.searchsorted(self.track, ids, "left"), np.searchsorted(self.track, ids, "right"))

    def n_status(self, status: int) -> NDArray[np.int64]:
        """Number of samples with ``status`` per track."""
        return np.bincount(self.track[self.status == status], minlength=self.n_tracks)

    def select(self, rows: NDArray) -> Tracks:
        """Rows ``rows`` (mask or indices), with track numbers made consecutive again."""
        return make_tracks(*(getattr(self, f.name)[rows] for f in fields(self)))

    def with_track(self, track: NDArray) -> Tracks:
        """The samples with track numbers ``track`` (one per sample; splitting, merging)."""
        return make_tracks(
            self.field, track, self.xyz_mm, self.corrected_mm, self.status, self.point
        )

    def positions(self, n_fields: int | None = None) -> NDArray[np.float64]:
        """Dense ``(n_tracks, n_fields, 3)`` array of positions, NaN where a track has none."""
        n = int(self.field.max()) + 1 if n_fields is None else n_fields
        out = np.full((self.n_tracks, n, 3), np.nan)
        out[self.track, self.field] = self.xyz_mm
        return out


def numbering(field: NDArray, track: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Track numbering used by :func:`make_tracks`: the distinct ``ids`` of ``track``, the
    new number ``rank[i]`` of ``ids[i]`` (ordered by first field, then id) and the index
    of each sample's id in ``ids``."""
    ids, inverse = np.unique(track, return_inverse=True)
    first = np.full(ids.size, np.iinfo(np.int64).max)
    np.minimum.at(first, inverse, field)
    rank = np.empty(ids.size, dtype=np.int64)
    rank[np.lexsort((ids, first))] = np.arange(ids.size)
    return ids, rank, inverse


def make_tracks(field, track, xyz_mm, corrected_mm, status, point) -> Tracks:
    """Build a :class:`Tracks`: sort by (track, field) and number tracks 0..n-1 in order
    of their first field (ties by old number)."""
    field = np.asarray(field, dtype=np.int64)
    track = np.asarray(track, dtype=np.int64)
    if track.size:
        _ids, rank, inverse = numbering(field, track)
        track = rank[inverse]
    order = np.lexsort((field, track))
    return Tracks(
        field=field[order],
        track=track[order],
        xyz_mm=np.asarray(xyz_mm, dtype=float).reshape(-1, 3)[order],
        corrected_mm=np.asarray(corrected_mm, dtype=float).reshape(-1, 3)[order],
        status=np.asarray(status, dtype=np.int8)[order],
        point=np.asarray(point, dtype=np.int64)[order],
    )
