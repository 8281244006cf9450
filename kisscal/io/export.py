"""Trajectory export for other tools: C3D (via ezc3d) and OpenSim TRC.

Both hold one point per track, named by its label, one frame per field from field 0 to
the last field, coordinates in mm. C3D frame numbers start at ``first_frame`` (1, or the
source file's first frame for a C3D trial: field k is frame ``first_frame + k``). Fields
where a track has no sample are missing (C3D: residual -1; TRC: empty cells).
The C3D residual is in the point units (mm), as the standard defines it: kisscal's
reconstruction residual (``rms_px``) times the size of a pixel at the point (see
:func:`kisscal.dlt.model.pixel_size_mm`). The C3D camera mask holds the first 7 cameras
only: :func:`write_sample_cameras` names them all.
"""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
from numpy.typing import NDArray

from kisscal.errors import InputError
from kisscal.gait.table import GaitEvents
from kisscal.io.c3d import patch_sample_words, point_scale, sample_words
from kisscal.io.files import atomic_path, write_text
from kisscal.io.points3d import Points3DFile
from kisscal.tracking.tracks import MEASURED, STATUS_NAMES, Tracks

#: Vicon's descriptions and icons of the two gait events (EVENT:DESCRIPTIONS, ICON_IDS).
_EVENT_STYLE = {
    "Foot Strike": ("The instant the heel strikes the ground", 1),
    "Foot Off": ("The instant the toe leaves the ground", 2),
}


def _dense(
    tracks: Tracks, labels: tuple[str, ...], rate_hz: float, n_fields: int | None = None
) -> np.ndarray:
    if len(labels) != tracks.n_tracks:
        raise InputError(f"export: {len(labels)} labels for {tracks.n_tracks} tracks")
    if len(set(labels)) != len(labels):
        raise InputError("export: point labels must be unique")
    if not rate_hz > 0:
        raise InputError(f"export: rate_hz must be > 0, got {rate_hz}")
    if tracks.field.size == 0:
        if not n_fields:
            raise InputError("export: no trajectories to write")
        return np.zeros((0, n_fields, 3))  # an empty trial: frames without points
    # (n_tracks, n_fields, 3): trailing fields without samples are fields too
    return tracks.positions(max(n_fields or 0, int(tracks.field.max()) + 1))


#: MANUFACTURER group of the C3D files kisscal writes (C3D.org 2023).
MANUFACTURER = {"COMPANY": "kisscal", "SOFTWARE": "kisscal"}


def write_c3d(
    path: str | Path,
    tracks: Tracks,
    labels: tuple[str, ...],
    rate_hz: float,
    *,
    points: Points3DFile | None = None,
    residual_mm: NDArray[np.float64] | None = None,
    events: GaitEvents | None = None,
    n_fields: int | None = None,
    first_frame: int = 1,
) -> Path:
    """Write trajectories as a C3D file: POINT:LABELS = labels, POINT:RATE = rate_hz,
    POINT:UNITS = mm, POINT:X_SCREEN / Y_SCREEN (+X, +Z: the lab's Z is up),
    POINT:DESCRIPTIONS, MANUFACTURER (COMPANY, SOFTWARE, VERSION_LABEL), the header's first
    frame and TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD from ``first_frame``, and
    ``events`` (foot strikes and foot offs) in the EVENT group (:func:`add_gait_events`).
    ``n_fields`` frames at least (trailing frames without samples are frames too); without
    trajectories and ``n_fields``, it is an error.

    Per sample, as the C3D standard reads it: measured samples carry their reconstruction
    residual in mm (``residual_mm``, one per row of ``points``, the trial's points3d.csv;
    unknown: the smallest positive residual) and the mask of the first 7 cameras that saw
    them; filled and predicted samples residual 0 and no cameras; fields without a sample
    residual -1 (see :func:`kisscal.io.c3d.sample_words`).
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
    c3d.add_parameter("POINT", "X_SCREEN", "+X")
    c3d.add_parameter("POINT", "Y_SCREEN", "+Z")
    for name, value in (*MANUFACTURER.items(), ("VERSION_LABEL", _version())):
        c3d.add_parameter("MANUFACTURER", name, value)
    _add_c3d_parameters(c3d, tracks, n_fields, rate_hz, first_frame)
    c3d["data"]["points"] = data
    if events is not None and len(events):
        add_gait_events(c3d, events, first_frame, rate_hz)
    words = _sample_words(tracks, points, residual_mm, n_fields, scale)
    path = Path(path)
    with atomic_path(path) as tmp:
        c3d.write(str(tmp))
        patch_sample_words(tmp, words, scale, first_frame)
    return path


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("kisscal")
    except PackageNotFoundError:  # pragma: no cover - a source tree not installed
        return "unknown"


def write_sample_cameras(
    path: str | Path, tracks: Tracks, labels: tuple[str, ...], points: Points3DFile
) -> Path:
    """``trajectories_cameras.csv``: ``field,label,cameras`` for every measured sample, the
    ids of every camera that saw it separated by spaces (the C3D camera mask holds only the
    first 7)."""
    measured = np.flatnonzero((tracks.status == MEASURED) & (tracks.point >= 0))
    lines = ["field,label,cameras"]
    if len(points.field):
        seen = points.blob[tracks.point[measured]] >= 0
        ids = np.array(points.camera_ids, dtype=object)
        for i, row in zip(measured.tolist(), seen, strict=True):
            lines.append(f"{tracks.field[i]},{labels[tracks.track[i]]},{' '.join(ids[row])}")
    write_text(Path(path), "\n".join(lines) + "\n")
    return Path(path)


def _sample_words(
    tracks: Tracks,
    points: Points3DFile | None,
    residual_mm: NDArray[np.float64] | None,
    n_fields: int,
    scale: float,
) -> np.ndarray:
    """The (n_fields, n_tracks) fourth C3D word of every sample (see ``sample_words``),
    -1 where a track has no sample."""
    row = np.where(tracks.point >= 0, tracks.point, 0)
    if points is not None and len(points.field):
        known = residual_mm is not None and len(residual_mm) == len(points.field)
        res = np.asarray(residual_mm, dtype=float)[row] if known else np.full(len(row), np.nan)
        rms = np.where(tracks.point >= 0, res, np.nan)
        seen = (points.blob[row] >= 0) & (tracks.point >= 0)[:, None]
    else:
        rms = np.full(len(tracks.field), np.nan)
        seen = np.zeros((len(tracks.field), 0), dtype=bool)
    words = np.full((n_fields, tracks.n_tracks), -1.0, dtype=np.float32)
    words[tracks.field, tracks.track] = sample_words(tracks.status, rms, seen, scale)
    return words


def _add_c3d_parameters(
    c3d: ezc3d.c3d, tracks: Tracks, n_fields: int, rate_hz: float, first_frame: int
) -> None:
    """TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD (frames first_frame.. , each as two
    16-bit words, low word first), TRIAL:CAMERA_RATE and one POINT:DESCRIPTIONS entry per
    trajectory."""
    last = first_frame + n_fields - 1
    for name, frame in (("ACTUAL_START_FIELD", first_frame), ("ACTUAL_END_FIELD", last)):
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


def add_gait_events(
    c3d: ezc3d.c3d, events: GaitEvents, first_frame: int = 1, rate_hz: float = 1.0
) -> None:
    """Gait events into the C3D EVENT group, in Vicon's layout.

    One entry per event, in time order: LABELS ``"Foot Strike"`` / ``"Foot Off"``,
    CONTEXTS ``"Left"`` / ``"Right"``, TIMES as (minutes, seconds) pairs counted, as Vicon
    does, from frame 1 at 0 s (field 0 is frame ``first_frame``: its events shift by
    ``(first_frame - 1) / rate_hz``), DESCRIPTIONS and
    ICON_IDS (1 foot strike, 2 foot off) as Vicon Nexus writes them, SUBJECTS empty (one
    subject), GENERIC_FLAGS 0, USED the count; written through ezc3d's ``add_event``.
    """
    table = events.c3d()
    shift_s = (first_frame - 1) / rate_hz
    for label, context, minutes, seconds in zip(
        table["LABELS"], table["CONTEXTS"], *table["TIMES"], strict=True
    ):
        description, icon = _EVENT_STYLE[label]
        total = 60.0 * float(minutes) + float(seconds) + shift_s
        c3d.add_event(
            [float(total // 60.0), float(total - 60.0 * (total // 60.0))],
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
        raise InputError(f"export: trc up axis must be 'z' or 'y', got {up!r}")
    dense = _dense(tracks, labels, rate_hz, n_fields) @ TRC_AXES[up].T
    n_tracks, n_fields, _ = dense.shape
    path = Path(path)
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
