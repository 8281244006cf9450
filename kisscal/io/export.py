"""Trajectory export for other tools: C3D (via ezc3d) and OpenSim TRC.

Both hold one point per track, named by its label, one frame per field from field 0 to
the last field (C3D frame k, counted from 1, is field k - 1), coordinates in mm. Fields
where a track has no sample are missing (C3D: residual -1; TRC: empty cells).
The C3D residual is kisscal's reconstruction residual in pixels (``rms_px``), not mm.
"""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np

from kisscal.errors import KisscalError
from kisscal.gait.table import GaitEvents
from kisscal.io.c3d import patch_sample_words, point_scale, sample_words
from kisscal.io.files import atomic_path, write_text
from kisscal.io.points3d import Points3DFile
from kisscal.tracking.tracks import STATUS_NAMES, Tracks

#: Vicon's descriptions and icons of the two gait events (EVENT:DESCRIPTIONS, ICON_IDS).
_EVENT_STYLE = {
    "Foot Strike": ("The instant the heel strikes the ground", 1),
    "Foot Off": ("The instant the toe leaves the ground", 2),
}


def _dense(
    tracks: Tracks, labels: tuple[str, ...], rate_hz: float, n_fields: int | None = None
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
    *,
    points: Points3DFile | None = None,
    events: GaitEvents | None = None,
    n_fields: int | None = None,
) -> Path:
    """Write trajectories as a C3D file: POINT:LABELS = labels, POINT:RATE = rate_hz,
    POINT:UNITS = mm, POINT:DESCRIPTIONS, TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD, and
    ``events`` (foot strikes and foot offs) in the EVENT group (:func:`add_gait_events`).
    Without trajectories, ``n_fields`` frames without points are written (a trial with no
    markers); without either, it is an error.

    Per sample, as the C3D standard reads it: measured samples carry their reconstruction
    residual (``rms_px`` of ``points``, the trial's points3d.csv, in pixels, > 0) and the
    mask of the cameras that saw them; filled and predicted samples residual 0 and no
    cameras; fields without a sample residual -1 (see :func:`kisscal.io.c3d.sample_words`).
    """
    dense = _dense(tracks, labels, rate_hz, n_fields)
    n_tracks, n_fields, _ = dense.shape
    data = np.ones((4, n_tracks, n_fields))
    data[:3] = np.transpose(dense, (2, 0, 1))
    scale = point_scale(dense)
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c3d["parameters"]["POINT"]["SCALE"]["value"] = [-scale]
    c3d.add_parameter("POINT", "UNITS", "mm")
    _add_c3d_parameters(c3d, tracks, n_fields, rate_hz)
    c3d["data"]["points"] = data
    if events is not None and len(events):
        add_gait_events(c3d, events)
    words = _sample_words(tracks, points, n_fields, scale)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        c3d.write(str(tmp))
        patch_sample_words(tmp, words, scale)
    return path


def _sample_words(
    tracks: Tracks, points: Points3DFile | None, n_fields: int, scale: float
) -> np.ndarray:
    """The (n_fields, n_tracks) fourth C3D word of every sample (see ``sample_words``),
    -1 where a track has no sample."""
    row = np.where(tracks.point >= 0, tracks.point, 0)
    if points is not None and len(points.field):
        rms = np.where(tracks.point >= 0, points.rms_px[row], np.nan)
        seen = (points.blob[row] >= 0) & (tracks.point >= 0)[:, None]
    else:
        rms = np.full(len(tracks.field), np.nan)
        seen = np.zeros((len(tracks.field), 0), dtype=bool)
    words = np.full((n_fields, tracks.n_tracks), -1.0, dtype=np.float32)
    words[tracks.field, tracks.track] = sample_words(tracks.status, rms, seen, scale)
    return words


def _add_c3d_parameters(c3d: ezc3d.c3d, tracks: Tracks, n_fields: int, rate_hz: float) -> None:
    """TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD (frames 1..n, each as two 16-bit words,
    low word first), TRIAL:CAMERA_RATE and one POINT:DESCRIPTIONS entry per trajectory."""
    for name, frame in (("ACTUAL_START_FIELD", 1), ("ACTUAL_END_FIELD", n_fields)):
        c3d.add_parameter("TRIAL", name, [frame & 0xFFFF, frame >> 16])
        c3d["parameters"]["TRIAL"][name]["type"] = ezc3d.ezc3d.INT  # lists become float
    c3d.add_parameter("TRIAL", "CAMERA_RATE", [float(rate_hz)])
    counts = {name: tracks.n_status(code) for code, name in enumerate(STATUS_NAMES)}
    descriptions = tuple(
        f"kisscal: {counts['measured'][t]} measured, "
        f"{sum(counts[n][t] for n in STATUS_NAMES if n.startswith('filled'))} filled, "
        f"{counts['predicted'][t]} predicted of {n_fields} fields"
        for t in range(tracks.n_tracks)
    )
    c3d["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = descriptions


def add_gait_events(c3d: ezc3d.c3d, events: GaitEvents) -> None:
    """Gait events into the C3D EVENT group, in Vicon's layout.

    One entry per event, in time order: LABELS ``"Foot Strike"`` / ``"Foot Off"``,
    CONTEXTS ``"Left"`` / ``"Right"``, TIMES as (minutes, seconds) pairs from the first
    frame (frame 1 at 0 s, as trajectories.c3d starts at field 0), DESCRIPTIONS and
    ICON_IDS (1 foot strike, 2 foot off) as Vicon Nexus writes them, SUBJECTS empty (one
    subject), GENERIC_FLAGS 0, USED the count; written through ezc3d's ``add_event``.
    """
    table = events.c3d()
    for label, context, minutes, seconds in zip(
        table["LABELS"], table["CONTEXTS"], *table["TIMES"], strict=True
    ):
        description, icon = _EVENT_STYLE[label]
        c3d.add_event(
            [float(minutes), float(seconds)],
            context=context,
            label=label,
            description=description,
            icon_id=icon,
        )


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
    n_fields: int | None = None,
) -> Path:
    """Write trajectories as an OpenSim TRC file (PathFileType 4, X/Y/Z, units mm).

    Frames are numbered from 1, time is ``(frame - 1) / rate_hz``. Every data row ends with
    a tab, as OpenSim's own writer does: OpenSim's tokenizer drops a trailing empty field,
    so a row whose last marker is missing would otherwise come one field short and the
    whole file would be refused. ``up`` is the vertical axis of the file (see
    :data:`TRC_AXES`); gaps are empty fields (NaN in OpenSim). Without trajectories,
    ``n_fields`` frames without markers, as :func:`write_c3d`.
    """
    if up not in TRC_AXES:
        raise KisscalError(f"export: trc up axis must be 'z' or 'y', got {up!r}")
    dense = _dense(tracks, labels, rate_hz, n_fields) @ TRC_AXES[up].T
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
