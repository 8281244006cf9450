"""Trajectory export for other tools: C3D (via ezc3d) and OpenSim TRC.

Both hold one point per track, named by its label, one frame per field from field 0 to
the last field (C3D frame k, counted from 1, is field k - 1), coordinates in mm. Fields
where a track has no sample are missing (C3D: residual -1; TRC: empty cells).
"""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np

from kisscal.errors import KisscalError
from kisscal.io.files import atomic_path, write_text
from kisscal.tracking.tracks import Tracks


def _dense(
    tracks: Tracks, labels: tuple[str, ...], rate_hz: float, n_fields: int | None
) -> np.ndarray:
    if len(labels) != tracks.n_tracks:
        raise KisscalError(f"export: {len(labels)} labels for {tracks.n_tracks} tracks")
    if len(set(labels)) != len(labels):
        raise KisscalError("export: point labels must be unique")
    if not rate_hz > 0:
        raise KisscalError(f"export: rate_hz must be > 0, got {rate_hz}")
    if tracks.field.size == 0:
        if not n_fields:
            raise KisscalError("export: no trajectories to write")
        return np.zeros((0, n_fields, 3))  # an empty trial: frames without points
    return tracks.positions()  # (n_tracks, n_fields, 3)


def write_c3d(
    path: str | Path,
    tracks: Tracks,
    labels: tuple[str, ...],
    rate_hz: float,
    n_fields: int | None = None,
) -> Path:
    """Write trajectories as a C3D file: POINT:LABELS = labels, POINT:RATE = rate_hz,
    POINT:UNITS = mm; missing samples are NaN (ezc3d stores residual -1).

    Without trajectories, ``n_fields`` frames without points are written (a trial with
    no markers); without either, it is an error."""
    dense = _dense(tracks, labels, rate_hz, n_fields)
    n_tracks, n_fields, _ = dense.shape
    points = np.ones((4, n_tracks, n_fields))
    points[:3] = np.transpose(dense, (2, 0, 1))
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c3d.add_parameter("POINT", "UNITS", "mm")
    c3d["data"]["points"] = points
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        c3d.write(str(tmp))
    return path


def write_trc(
    path: str | Path,
    tracks: Tracks,
    labels: tuple[str, ...],
    rate_hz: float,
    n_fields: int | None = None,
) -> Path:
    """Write trajectories as an OpenSim TRC file (PathFileType 4, X/Y/Z, units mm);
    frames are numbered from 1, time is (frame - 1) / rate_hz. Without trajectories,
    ``n_fields`` frames without markers, as :func:`write_c3d`."""
    dense = _dense(tracks, labels, rate_hz, n_fields)
    n_tracks, n_fields, _ = dense.shape
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        f"{rate_hz:.2f}\t{rate_hz:.2f}\t{n_fields}\t{n_tracks}\tmm\t{rate_hz:.2f}\t1\t{n_fields}",
        "Frame#\tTime\t" + "\t".join(f"{lab}\t\t" for lab in labels).rstrip("\t"),
        "\t\t" + "\t".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}" for i in range(n_tracks)),
        "",
    ]
    values = np.transpose(dense, (1, 0, 2)).reshape(n_fields, 3 * n_tracks)
    text = np.where(np.isfinite(values), np.char.mod("%.3f", np.nan_to_num(values)), "")
    for f in range(n_fields):
        lines.append("\t".join([f"{f + 1}", f"{f / rate_hz:.5f}", *text[f]]))
    if n_tracks == 0:  # frame and time columns alone, no dangling separators
        lines = [line.rstrip("\t") for line in lines]
    write_text(path, "\n".join(lines) + "\n")
    return path
