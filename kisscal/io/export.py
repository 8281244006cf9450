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


def _dense(tracks: Tracks, labels: tuple[str, ...], rate_hz: float) -> np.ndarray:
    if len(labels) != tracks.n_tracks:
        raise KisscalError(f"export: {len(labels)} labels for {tracks.n_tracks} tracks")
    if len(set(labels)) != len(labels):
        raise KisscalError("export: point labels must be unique")
    if not rate_hz > 0:
        raise KisscalError(f"export: rate_hz must be > 0, got {rate_hz}")
    if tracks.field.size == 0:
        raise KisscalError("export: no trajectories to write")
    return tracks.positions()  # (n_tracks, n_fields, 3)


def write_c3d(path: str | Path, tracks: Tracks, labels: tuple[str, ...], rate_hz: float) -> Path:
    """Write trajectories as a C3D file: POINT:LABELS = labels, POINT:RATE = rate_hz,
    POINT:UNITS = mm; missing samples are NaN (ezc3d stores residual -1)."""
    dense = _dense(tracks, labels, rate_hz)
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


#: Lab axes as TRC axes: ``"z"`` keeps the lab frame (Z up); ``"y"`` turns it Y-up as OpenSim
#: models expect (TRC X = lab X, TRC Y = lab Z, TRC Z = -lab Y; a rotation, still right-handed).
TRC_AXES: dict[str, np.ndarray] = {
    "z": np.eye(3),
    "y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}


def write_trc(
    path: str | Path,
    tracks: Tracks,
    labels: tuple[str, ...],
    rate_hz: float,
    up: str = "z",
) -> Path:
    """Write trajectories as an OpenSim TRC file (PathFileType 4, X/Y/Z, units mm).

    Frames are numbered from 1, time is ``(frame - 1) / rate_hz``. Every data row ends with
    a tab, as OpenSim's own writer does: OpenSim's tokenizer drops a trailing empty field,
    so a row whose last marker is missing would otherwise come one field short and the
    whole file would be refused. ``up`` is the vertical axis of the file (see
    :data:`TRC_AXES`); gaps are empty fields (NaN in OpenSim).
    """
    if up not in TRC_AXES:
        raise KisscalError(f"export: trc up axis must be 'z' or 'y', got {up!r}")
    dense = _dense(tracks, labels, rate_hz) @ TRC_AXES[up].T
    n_tracks, n_fields, _ = dense.shape
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
        "OrigDataStartFrame\tOrigNumFrames",
        f"{rate_hz:.2f}\t{rate_hz:.2f}\t{n_fields}\t{n_tracks}\tmm\t{rate_hz:.2f}\t1\t{n_fields}",
        "Frame#\tTime\t" + "".join(f"{lab}\t\t\t" for lab in labels),
        "\t\t" + "".join(f"X{i + 1}\tY{i + 1}\tZ{i + 1}\t" for i in range(n_tracks)),
        "",
    ]
    values = np.transpose(dense, (1, 0, 2)).reshape(n_fields, 3 * n_tracks)
    text = np.where(np.isfinite(values), np.char.mod("%.3f", np.nan_to_num(values)), "")
    for f in range(n_fields):
        lines.append(f"{f + 1}\t{f / rate_hz:.5f}\t" + "".join(v + "\t" for v in text[f]))
    write_text(path, "\n".join(lines) + "\n")
    return path
