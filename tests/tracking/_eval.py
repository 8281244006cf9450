"""Scoring of trajectories against truth (tests and the acceptance measurement)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kisscal.tracking import FILLED, MEASURED, PREDICTED, Trajectories, is_filled


@dataclass(frozen=True)
class Score:
    n_markers: int
    n_tracks: int
    one_per_marker: bool
    labels_correct: int
    identity_switches: int
    coverage: float
    coverage_visible: float
    rmse_measured_mm: float
    rmse_filled_mm: float
    rmse_predicted_mm: float
    n_filled: int
    track_marker: tuple[int, ...]


def score(result: Trajectories, truth: np.ndarray, visible: np.ndarray, names) -> Score:
    """Compare with truth (n_markers, n_fields, 3) and visibility (n_markers, n_fields).

    Each sample belongs to the true marker nearest to it at its field; a track's marker
    is its majority; an identity switch is a track with samples of more than one marker
    (measured samples only). ``coverage`` is over the fields between each marker's first
    and last visible field; ``coverage_visible`` over the fields where it is visible (the
    marker-fields reconstruction can deliver).
    """
    tr = result.tracks
    n_markers = truth.shape[0]
    d = np.linalg.norm(truth[:, tr.field, :] - tr.xyz_mm[None], axis=2)  # (M, S)
    nearest = d.argmin(axis=0)
    track_marker = []
    switches = 0
    for t in range(tr.n_tracks):
        rows = (tr.track == t) & (tr.status == MEASURED)
        ids = nearest[rows]
        major = np.bincount(ids, minlength=n_markers).argmax() if ids.size else -1
        track_marker.append(int(major))
        if ids.size and np.any(ids != major):
            switches += 1
    track_marker = np.array(track_marker)
    one_per_marker = tr.n_tracks == n_markers and np.unique(track_marker).size == n_markers
    labels_correct = sum(
        1 for t, m in enumerate(track_marker) if m >= 0 and result.labels[t] == names[m]
    )
    covered = np.zeros_like(visible)
    ok = (tr.status == MEASURED) | is_filled(tr.status)
    covered[track_marker[tr.track[ok]], tr.field[ok]] = True
    span = np.zeros_like(visible)
    for m in range(n_markers):
        f = np.flatnonzero(visible[m])
        if f.size:
            span[m, f[0] : f[-1] + 1] = True
    coverage = (covered & span).sum() / span.sum()
    coverage_visible = (covered & visible).sum() / visible.sum()
    own = truth[track_marker[tr.track], tr.field]
    err = np.linalg.norm(tr.xyz_mm - own, axis=1)

    def rmse(status):
        e = err[is_filled(tr.status)] if status == FILLED else err[tr.status == status]
        return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")

    return Score(
        n_markers,
        tr.n_tracks,
        bool(one_per_marker),
        labels_correct,
        switches,
        float(coverage),
        float(coverage_visible),
        rmse(MEASURED),
        rmse(FILLED),
        rmse(PREDICTED),
        int(is_filled(tr.status).sum()),
        tuple(int(v) for v in track_marker),
    )
