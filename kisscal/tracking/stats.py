"""Statistics of trajectories as in Küçük 2005 chapter 5.

Per segment (a pair of markers): mean, variance, standard deviation and SD/mean of its
length, from the measured points and from the Kalman a-posteriori ("corrected") estimates
(tables 5.1-5.12); per track, the number of missing-point predictions (table 5.13).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import InputError
from kisscal.tracking.tracks import MEASURED, Tracks


@dataclass(frozen=True)
class SegmentStats:
    """Length statistics of one segment from one kind of estimate.

    ``kind`` is ``"measured"`` or ``"corrected"``; lengths in mm, variance in mm²;
    ``n_fields`` counts the fields where both ends had that estimate.
    """

    segment: tuple[str, str]
    kind: str
    n_fields: int
    mean_mm: float
    variance_mm2: float
    sd_mm: float
    sd_over_mean: float


def _dense(tracks: Tracks, values: NDArray, rows: NDArray, n_fields: int) -> NDArray:
    out = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    out[tracks.track[rows], tracks.field[rows]] = values[rows]
    return out


def segment_statistics(
    tracks: Tracks, labels: tuple[str, ...], segments: list[tuple[str, str]] | tuple
) -> list[SegmentStats]:
    """Length statistics of each segment whose two markers were labelled.

    Measured lengths use fields where both markers were measured; corrected lengths use
    the Kalman a-posteriori estimates at fields where both ends have one. The variance is
    the population variance (ddof = 0).
    """
    if tracks.field.size == 0:
        return []
    index = {name: i for i, name in enumerate(labels)}
    n_fields = int(tracks.field.max()) + 1
    measured = _dense(tracks, tracks.xyz_mm, np.flatnonzero(tracks.status == MEASURED), n_fields)
    corrected = _dense(tracks, tracks.corrected_mm, np.arange(tracks.field.size), n_fields)
    out = []
    for pair in segments:
        if len(pair) != 2:
            raise InputError(f"markers: a segment needs two marker names, got {pair!r}")
        a, b = pair
        if a not in index or b not in index:
            continue
        for kind, dense in (("measured", measured), ("corrected", corrected)):
            length = np.linalg.norm(dense[index[a]] - dense[index[b]], axis=1)
            length = length[np.isfinite(length)]
            if length.size == 0:
                continue
            mean = float(length.mean())
            var = float(length.var())
            sd = float(np.sqrt(var))
            out.append(SegmentStats((a, b), kind, int(length.size), mean, var, sd, sd / mean))
    return out
