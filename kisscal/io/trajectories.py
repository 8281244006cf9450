"""trajectories.csv: ``field,track,label,x_mm,y_mm,z_mm,status`` (DESIGN.md), and the CSV of
the PNC x MNC sweep (Küçük 2005 tables 5.1-5.13)."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import InputError
from kisscal.io.files import read_text, write_csv
from kisscal.tracking.pipeline import SweepRow
from kisscal.tracking.tracks import LEGACY_STATUS, STATUS_NAMES, Tracks

HEADER = ("field", "track", "label", "x_mm", "y_mm", "z_mm", "status")
SWEEP_HEADER = (
    "pnc",
    "mnc",
    "segment",
    "kind",
    "n_fields",
    "mean_mm",
    "variance_mm2",
    "sd_mm",
    "sd_over_mean",
)
PREDICTION_HEADER = ("pnc", "mnc", "label", "n_predicted")


@dataclass(frozen=True)
class TrajectoryTable:
    """Rows of a trajectories.csv, in file order."""

    field: NDArray[np.int64]
    track: NDArray[np.int64]
    label: NDArray[np.str_]
    xyz_mm: NDArray[np.float64]
    status: NDArray[np.int8]

    def labels(self) -> tuple[str, ...]:
        """Label of each track number 0..max (empty where a number is unused)."""
        out = [""] * (int(self.track.max()) + 1 if self.track.size else 0)
        for t, lab in zip(self.track, self.label, strict=True):
            out[t] = str(lab)
        return tuple(out)


def write_trajectories_csv(path: str | Path, tracks: Tracks, labels: tuple[str, ...]) -> Path:
    """Write one row per sample: ``field,track,label,x_mm,y_mm,z_mm,status``, sorted by
    track then field, coordinates to 0.001 mm."""
    if len(labels) != tracks.n_tracks:
        raise InputError(f"trajectories: {len(labels)} labels for {tracks.n_tracks} tracks")
    path = Path(path)
    names = np.asarray(labels, dtype=object)[tracks.track]
    status = np.asarray(STATUS_NAMES, dtype=object)[tracks.status]
    rows = (
        (int(f), int(t), lab, f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", st)
        for f, t, lab, (x, y, z), st in zip(
            tracks.field, tracks.track, names, tracks.xyz_mm, status, strict=True
        )
    )
    return write_csv(path, HEADER, rows)


def read_trajectories_csv(path: str | Path) -> TrajectoryTable:
    """Read a trajectories.csv written by :func:`write_trajectories_csv` (or any tool
    following DESIGN.md); ``status`` ``filled`` of files before contract version 3 reads
    as ``filled_spline``."""
    path = Path(path)
    rows = list(csv.reader(io.StringIO(read_text(path, "trajectories file"))))
    if not rows or tuple(rows[0]) != HEADER:
        raise InputError(f"trajectories: {path} must start with the header {','.join(HEADER)}")
    body = rows[1:]
    code = {**LEGACY_STATUS, **{name: i for i, name in enumerate(STATUS_NAMES)}}
    try:
        field = np.array([int(r[0]) for r in body], dtype=np.int64)
        track = np.array([int(r[1]) for r in body], dtype=np.int64)
        label = np.array([r[2] for r in body], dtype=str)
        xyz = np.array([[float(v) for v in r[3:6]] for r in body]).reshape(-1, 3)
        status = np.array([code[r[6]] for r in body], dtype=np.int8)
    except (ValueError, IndexError, KeyError) as exc:
        raise InputError(f"trajectories: bad row in {path}: {exc}") from None
    return TrajectoryTable(field, track, label, xyz, status)


def write_sweep_csv(path: str | Path, rows: list[SweepRow]) -> Path:
    """Write the segment-length table of :func:`kisscal.tracking.sweep_noise`: one row per
    (pnc, mnc, segment, kind); and beside it ``<stem>_predictions.csv`` with the number of
    missing-point predictions per (pnc, mnc, label) (thesis table 5.13)."""
    path = Path(path)
    segments = (
        (row.pnc, row.mnc, f"{s.segment[0]}-{s.segment[1]}", s.kind, s.n_fields)
        + (f"{s.mean_mm:.3f}", f"{s.variance_mm2:.3f}", f"{s.sd_mm:.3f}", f"{s.sd_over_mean:.4f}")
        for row in rows
        for s in row.segments
    )
    write_csv(path, SWEEP_HEADER, segments)
    predictions = (
        (row.pnc, row.mnc, label, n) for row in rows for label, n in row.predictions.items()
    )
    write_csv(path.with_name(f"{path.stem}_predictions.csv"), PREDICTION_HEADER, predictions)
    return path
