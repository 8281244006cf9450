"""C3D files: reading marker trajectories as the C3D standard defines them, and the parts
of writing that ezc3d does not do as the standard asks (the per-sample residual and camera
mask word, the header's scale).

Reading keeps markers only (declared model outputs, Plug-in Gait's segment axes and
channels fixed to the bit in one coordinate are left out and listed) and every frame,
with the file's own first frame number. Intel and DEC files are read with ezc3d;
SGI/MIPS files, which ezc3d does not read, with the ``c3d`` package.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.io.c3d_computed import copies, flat_channels
from kisscal.io.c3d_data import (
    header_fits,
    header_holds,
    header_layout,
    header_rate,
    read_points_by_header,
)
from kisscal.tracking.tracks import MEASURED

#: POINT parameters whose values name channels that hold model outputs, not markers.
MODEL_OUTPUT_GROUPS = (
    "ANGLES",
    "FORCES",
    "MOMENTS",
    "POWERS",
    "SCALARS",
    "REACTIONS",
    "MODELED_MARKERS",
)

#: Processor type byte of the parameter section (C3D.org 2023): 84 + n.
PROCESSORS = {84: "Intel", 85: "DEC", 86: "MIPS"}

#: POINT:UNITS to millimetres: the symbols, and the words (some writers spell the unit out,
#: some cut it to the parameter's length: Peak Performance's "mete").
_UNITS_MM = {"mm": 1.0, "m": 1000.0, "cm": 10.0}
_UNIT_WORDS = {"millimeter": 1.0, "millimetre": 1.0, "centimeter": 10.0, "centimetre": 10.0}
_UNIT_WORDS |= {"meter": 1000.0, "metre": 1000.0}


@dataclass(frozen=True)
class C3DPoints:
    """The markers of a C3D file.

    Attributes
    ----------
    labels : tuple of str
        Marker labels (``POINT:LABELS`` continued by ``LABELS2`` ..., stripped).
    xyz_mm : (n_frames, n_markers, 3) float
        Positions in mm, NaN where a sample is invalid (negative residual, or stored at
        exactly 0 0 0 as older writers mark a missing sample). Every frame of the file,
        empty ones included.
    rate_hz : float
        ``POINT:RATE``.
    first_frame : int
        The file's number of its first frame (``TRIAL:ACTUAL_START_FIELD`` when present,
        else the header's first frame; counted from 1).
    excluded : tuple of str
        Labels of the channels left out: declared model outputs, segment axis points
        and computed channels (a coordinate exactly constant: floor projections, scalars).
    processor : str
        ``Intel``, ``DEC`` or ``MIPS``.
    manufacturer : str
        ``MANUFACTURER:COMPANY`` and ``SOFTWARE`` (empty when the file does not say).
    """

    labels: tuple[str, ...]
    xyz_mm: NDArray[np.float64]
    rate_hz: float
    first_frame: int
    excluded: tuple[str, ...]
    processor: str
    manufacturer: str

    @property
    def n_frames(self) -> int:
        return int(self.xyz_mm.shape[0])


def processor_type(path: Path) -> str:
    """``Intel``, ``DEC`` or ``MIPS``: the fourth byte of the parameter section, whose
    first block the header's first byte gives (C3D.org 2023, the parameter header)."""
    with Path(path).open("rb") as fh:
        head = fh.read(2)
        if len(head) < 2 or head[1] != 0x50:  # the C3D key byte
            raise InputError(f"{path}: not a C3D file (no C3D key in its header)")
        fh.seek((max(head[0], 1) - 1) * 512)
        block = fh.read(4)
    kind = PROCESSORS.get(block[3] if len(block) == 4 else -1)
    if kind is None:
        raise InputError(f"{path}: unknown C3D processor type (parameter byte 4)")
    return kind


def read_c3d(path: Path) -> C3DPoints:
    """The markers of a C3D file (see :class:`C3DPoints`).

    Parameters
    ----------
    path : Path
        A C3D file of any processor type (Intel, DEC, SGI/MIPS), integer or float data.

    Returns
    -------
    C3DPoints

    References
    ----------
    C3D.org (2023). The C3D file format user guide: the POINT group (LABELS2, UNITS,
    SCALE), the TRIAL group (ACTUAL_START_FIELD) and the processor types.
    Motion Lab Systems (2008). The C3D file format, a technical user guide (model outputs
    stored as points: ANGLES, FORCES, MOMENTS, POWERS).
    Vicon Motion Systems (2016). Plug-in Gait reference guide (the segments' axis points
    written as points: origin, anterior, lateral, proximal).
    """
    path = Path(path)
    if not path.is_file():
        raise MissingDataError(f"{path}: C3D file not found")
    processor = processor_type(path)
    params, xyz, residual, header_first, rate = _read_either(path, processor)
    if header_holds(path, processor, params, rate):  # the parameters misdescribe the data
        xyz, residual, header_first = read_points_by_header(path, processor)
    return _markers(path, params, xyz, residual, header_first, rate, processor)


def no_points(xyz_mm: NDArray) -> str:
    """Why a C3D file gives no 3D point to track ('' when it gives some): no point channel
    at all (force plates, EMG or rotations only: such files often store a point rate of
    0), or channels without a valid sample."""
    if xyz_mm.shape[1] == 0:
        return "the file holds no 3D points (analog or other data only)"
    if not np.isfinite(xyz_mm).all(axis=2).any():
        return "no valid 3D point in the file"
    return ""


def read_c3d_points(path: Path) -> tuple[tuple[str, ...], NDArray[np.float64], float]:
    """Marker labels, positions (n_frames, n_markers, 3) in mm (NaN where invalid) and
    rate of a C3D file: :func:`read_c3d` without its frame numbering and log."""
    c3d = read_c3d(path)
    return c3d.labels, c3d.xyz_mm, c3d.rate_hz


# ------------------------------------------------------------------ reading: the two backends


def _read_either(path: Path, processor: str) -> _Raw:
    """The file through ezc3d, or through the ``c3d`` package where ezc3d cannot read it
    (SGI/MIPS files; files whose parameters break the standard in ways ezc3d refuses, such
    as a float ``ANALOG:OFFSET``; files with points in the data but none described by the
    parameters, where the header's point count holds); one clear error if neither can."""
    errors = []
    readers = (_read_c3d_package,) if processor == "MIPS" else (_read_ezc3d, _read_c3d_package)
    for reader in readers:
        try:
            raw = reader(path)
        except KisscalError:
            raise
        except Exception as exc:  # both readers raise plain exceptions on corrupt files
            errors.append(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
            continue
        if reader is _read_ezc3d and raw[1].shape[1] < header_layout(path, processor)["points"]:
            continue  # the parameters describe fewer points than the data holds
        return raw
    if header_fits(path, processor):
        # Neither reader parses the parameter section (BTK's test files of a broken
        # parameter offset), but the header alone lays out the data and fills the file:
        # the points, unnamed, in mm (the standard's default unit), at the header's rate.
        xyz, residual, first = read_points_by_header(path, processor)
        return {}, xyz, residual, first, header_rate(path, processor)
    reasons = "; ".join(_IGNORE_HINT.sub("", e).strip(" :") for e in errors)
    raise InputError(f"{path}: not a readable C3D file ({reasons})") from None


#: ezc3d's advice to set its own ignoreBadFormatting flag, which a kisscal user cannot.
_IGNORE_HINT = re.compile(r"\s*If you want to ignore this error, set \w+ to true\.?:?", re.I)


#: A file as both backends give it: parameters {(GROUP, NAME): values}, positions
#: (n_frames, n_points, 3) in file units, residuals (n_frames, n_points), the header's
#: first frame (from 1) and the point rate.
_Raw = tuple[dict[tuple[str, str], list], NDArray, NDArray, int, float]


def _read_ezc3d(path: Path) -> _Raw:
    import ezc3d

    c3d = ezc3d.c3d(str(path))
    params = {
        (group.upper(), name.upper()): list(np.ravel(entry["value"]))
        for group, entries in c3d["parameters"].items()
        for name, entry in entries.items()
        if isinstance(entry, dict) and "value" in entry
    }
    xyz = c3d["data"]["points"][:3].transpose(2, 1, 0)
    if xyz.shape[1]:
        residual = c3d["data"]["meta_points"]["residuals"][0].T
    else:  # a file without points (ezc3d gives no residual array then)
        residual = np.zeros(xyz.shape[:2])
    header = c3d["header"]["points"]
    # ezc3d counts the header's first frame from 0; the standard from 1
    return params, xyz, residual, int(header["first_frame"]) + 1, float(header["frame_rate"])


def _read_c3d_package(path: Path) -> _Raw:
    import warnings

    import c3d

    with path.open("rb") as fh, warnings.catch_warnings():
        # it warns of each odd parameter it works round (kisscal's fallback reader: the
        # files it reads here are odd by definition)
        warnings.simplefilter("ignore")
        reader = c3d.Reader(fh)
        params: dict[tuple[str, str], list] = {}
        for group_name, group in reader.group_items():
            for name, param in group.param_items():
                params[(group_name.upper(), name.upper())] = _package_values(param)
        frames = [points for _, points, _ in reader.read_frames(copy=True)]
        first, rate = int(reader.first_frame), float(reader.point_rate)
    data = np.stack(frames) if frames else np.zeros((0, 0, 5))
    return params, data[..., :3], data[..., 3], first, rate


def _package_values(param: object) -> list:
    """A ``c3d`` package parameter's values as ezc3d gives them: strings, or numbers (a
    scalar as one value; values the package cannot read as none)."""
    size = getattr(param, "bytes_per_element", 0)
    if size == -1:
        return [str(s) for s in np.atleast_1d(param.string_array)]  # type: ignore[attr-defined]
    kind = {1: "int8", 2: "int16", 4: "float"}.get(size)
    for attr in (f"{kind}_array", f"{kind}_value"):
        try:
            return list(np.ravel(getattr(param, attr)))
        except Exception:  # the package raises plain errors on shapes it does not take
            continue
    return []


# ------------------------------------------------------------------ reading: markers only


def _strings(params: dict[tuple[str, str], list], group: str, name: str) -> list[str]:
    return [str(v).strip() for v in params.get((group, name), [])]


def _continued(params: dict[tuple[str, str], list], group: str, name: str) -> list[str]:
    """A string parameter and its continuations ``NAME2``, ``NAME3`` ... (C3D.org 2023:
    more than 255 entries)."""
    out = _strings(params, group, name)
    k = 2
    while (group, f"{name}{k}") in params:
        out += _strings(params, group, f"{name}{k}")
        k += 1
    return out


def _model_outputs(params: dict[tuple[str, str], list]) -> set[str]:
    """Labels the POINT group declares as model outputs."""
    groups = set(MODEL_OUTPUT_GROUPS) | {
        s.upper() for s in _strings(params, "POINT", "TYPE_GROUPS")
    }
    names: set[str] = set()
    for (group, name), values in params.items():
        base = re.sub(r"\d+$", "", name)
        if group == "POINT" and base in groups and name not in ("LABELS", "DESCRIPTIONS"):
            names |= {str(v).strip() for v in values if str(v).strip()}
    return names


#: The suffixes of a segment's axis points as Plug-in Gait writes them: origin, anterior,
#: lateral and proximal point of the segment (Vicon Motion Systems 2016); the Oxford foot
#: model's numbers them: origin 0 and the ends of its three axes 1, 2, 3 (``LFOF0`` ...
#: ``LFOF3``, Carson et al. 2001 as Vicon's Oxford Foot Model plug-in writes it).
SEGMENT_AXES = ("O", "A", "L", "P")
NUMBERED_AXES = ("0", "1", "2", "3")


def _segment_axes(labels: list[str]) -> set[str]:
    """Labels that are a segment's axis points: all four of ``<segment>O``, ``A``, ``L``,
    ``P`` present (subject prefix ``Name:`` aside), the segment named by two letters or
    more; all four of ``<segment>0`` ... ``3``, the segment named by three letters or more
    and only letters (the Oxford foot model's; numbered markers such as ``Marker_10`` ...
    ``Marker_13`` or ``PT00`` ... ``PT03`` are not); or all four of
    ``o_<segment>``, ``x_``, ``y_``, ``z_`` (origin and axis ends, as a Vicon lab's model
    writes ``o_Trunk`` ... ``z_Trunk``). Plug-in Gait stores them as
    plain points in no model-output group; they move with their segment like markers,
    and crowd a marker set's template (a walking trial holds 36 of them beside 18
    markers)."""
    bare = {lab: lab.rsplit(":", 1)[-1].strip().upper() for lab in labels}
    names = set(bare.values())
    out = set()
    for suffixes in (SEGMENT_AXES, NUMBERED_AXES):
        segments = {
            b[:-1]
            for b in names
            if len(b) >= 3 + (suffixes is NUMBERED_AXES)
            and (b[:-1].isalpha() or suffixes is SEGMENT_AXES)
            and all(b[:-1] + s in names for s in suffixes)
        }
        out |= {lab for lab, b in bare.items() if b[:-1] in segments and b[-1] in suffixes}
    axes = {b[2:] for b in names if len(b) >= 4 and all(f"{s}_{b[2:]}" in names for s in "OXYZ")}
    return out | {
        lab for lab, b in bare.items() if b[:2] in ("O_", "X_", "Y_", "Z_") and b[2:] in axes
    }


def _unit_mm(units: str) -> float | None:
    """Millimetres per POINT:UNITS unit: a symbol, or a unit word in the singular or the
    plural, whole or cut after at least three letters (None: not a length unit)."""
    if units in _UNITS_MM:
        return _UNITS_MM[units]
    word = units.rstrip("s") if len(units) > 3 else units
    hits = {mm for name, mm in _UNIT_WORDS.items() if len(word) >= 3 and name.startswith(word)}
    return hits.pop() if len(hits) == 1 else None


def _first_frame(params: dict[tuple[str, str], list], header_first: int) -> int:
    """TRIAL:ACTUAL_START_FIELD (two 16-bit words, low first: frames past 65535) when the
    file has it, else the header's first frame."""
    words = [int(v) & 0xFFFF for v in params.get(("TRIAL", "ACTUAL_START_FIELD"), [])]
    if len(words) >= 2 and (words[0] or words[1]):
        return words[0] + (words[1] << 16)
    return header_first


def _markers(
    path: Path,
    params: dict[tuple[str, str], list],
    xyz: NDArray,
    residual: NDArray,
    header_first: int,
    rate: float,
    processor: str,
) -> C3DPoints:
    n_points = xyz.shape[1]
    labels = _continued(params, "POINT", "LABELS")[:n_points]
    labels += [f"point{i + 1}" for i in range(len(labels), n_points)]  # unnamed channels
    units = (_strings(params, "POINT", "UNITS") or ["mm"])[0].lower() or "mm"
    scale = _unit_mm(units)
    if scale is None:
        raise InputError(f"{path}: unsupported point units {units!r} (mm, cm or m)")
    # Invalid: a negative residual, or (older writers) a sample stored at exactly 0 0 0
    # with a valid residual (no real marker sits on the origin to the last bit).
    missing = (residual < 0) | (xyz == 0).all(axis=2)
    xyz = np.where(missing[..., None], np.nan, xyz.astype(float) * scale)
    outputs = _model_outputs(params) | _segment_axes(labels)
    keep = np.array([lab not in outputs for lab in labels], dtype=bool) & ~flat_channels(xyz)
    keep[keep] = ~copies(xyz[:, keep])
    maker = [s for key in ("COMPANY", "SOFTWARE") for s in _strings(params, "MANUFACTURER", key)]
    return C3DPoints(
        labels=tuple(lab for lab, k in zip(labels, keep, strict=True) if k),
        xyz_mm=xyz[:, keep],
        rate_hz=rate,
        first_frame=_first_frame(params, header_first),
        excluded=tuple(lab for lab, k in zip(labels, keep, strict=True) if not k),
        processor=processor,
        manufacturer=" ".join(s for s in maker if s),
    )


# ------------------------------------------------------------------ writing: per-sample words

#: Cameras a C3D camera mask can name: 7 bits (the word's top bit is the residual's sign).
C3D_MASK_CAMERAS = 7


def sample_words(
    status: NDArray[np.int8],
    residual: NDArray[np.float64],
    cameras: NDArray[np.bool_],
    scale: float,
) -> NDArray[np.float32]:
    """The fourth word of each valid C3D point sample, as the C3D standard defines it.

    The word is an integer stored as a float: its high byte holds the camera mask (bit
    ``k`` for camera ``k``, the first 7 cameras), its low byte the residual divided by
    ``|POINT:SCALE|``. A measured sample gets its reconstruction residual, rounded and
    kept >= 1 so that it never reads as 0 (which means interpolated or modelled data);
    filled and predicted samples get 0 in both bytes, as the standard asks.

    Parameters
    ----------
    status : (S,) int8
        :data:`~kisscal.tracking.tracks.MEASURED`, ``PREDICTED`` or ``FILLED``.
    residual : (S,) float
        Reconstruction residual of the sample in the point units (mm; NaN when unknown:
        stored as the smallest positive residual).
    cameras : (S, n_cameras) bool
        Cameras the sample was seen by.
    scale : float
        ``|POINT:SCALE|``.

    References
    ----------
    C3D.org (2023). The C3D file format user guide: 3D point data, integer and
    floating-point formats (camera mask in the high byte, residual in the low byte).
    """
    measured = np.asarray(status) == MEASURED
    steps = np.nan_to_num(np.asarray(residual, dtype=float) / scale, nan=1.0, posinf=255.0)
    residual = np.clip(np.round(steps), 1, 255).astype(np.int64)
    bits = np.asarray(cameras, dtype=bool)[:, :C3D_MASK_CAMERAS]
    mask = (bits * (1 << np.arange(bits.shape[1]))).sum(axis=1).astype(np.int64)
    return np.where(measured, (mask << 8) | residual, 0).astype(np.float32)


def patch_sample_words(
    path: Path, words: NDArray[np.float32], scale: float, first_frame: int = 1
) -> None:
    """Set the fourth word of every point sample of a float C3D file, in place, the
    header's scale factor to ``-scale`` (POINT:SCALE's value) and its first and last frame
    numbers from ``first_frame`` (16-bit words: frames past 65535 are kept in
    TRIAL:ACTUAL_START_FIELD only).

    ``words`` has shape (n_frames, n_points); a negative word marks a gap, stored as the
    standard asks (-1, coordinates 0). ezc3d (1.7) writes the camera mask into the low
    byte and the residual into the high byte, the reverse of the standard that Vicon,
    Mokka and the ``c3d`` package read, gaps with residual 0, and the header's scale as -1
    whatever POINT:SCALE says; kisscal writes the standard.
    """
    with Path(path).open("r+b") as fh:
        head = np.frombuffer(fh.read(512), dtype="<i2").copy()
        n_points, n_analog, start_block = int(head[1]), int(head[2]), int(head[8])
        n_frames = int(head[4]) - int(head[3]) + 1
        if float(head[6:8].view("<f4")[0]) >= 0 or words.shape != (n_frames, n_points):
            raise InputError(f"{path}: not the float C3D layout kisscal writes")
        head[6:8] = np.array([-scale], dtype="<f4").view("<i2")
        if first_frame + n_frames - 1 <= 0xFFFF:
            frames = head.view("<u2")  # frame numbers are unsigned words
            frames[3], frames[4] = first_frame, first_frame + n_frames - 1
        fh.seek(0)
        fh.write(head.tobytes())
        frame_size = 4 * n_points + n_analog
        fh.seek((start_block - 1) * 512)
        data = np.frombuffer(fh.read(4 * frame_size * n_frames), dtype="<f4").copy()
        samples = data.reshape(n_frames, frame_size)[:, : 4 * n_points].reshape(
            n_frames, n_points, 4
        )
        gap = words < 0
        samples[..., 3] = np.where(gap, -1.0, words)
        samples[gap, :3] = 0.0
        data.reshape(n_frames, frame_size)[:, : 4 * n_points] = samples.reshape(n_frames, -1)
        fh.seek((start_block - 1) * 512)
        fh.write(data.astype("<f4").tobytes())


def point_scale(xyz_mm: NDArray[np.float64]) -> float:
    """``|POINT:SCALE|`` as the standard asks: the largest coordinate / 32000 (a float
    file keeps it for the residual and for conversion to the integer format)."""
    largest = float(np.nanmax(np.abs(xyz_mm))) if np.isfinite(xyz_mm).any() else 0.0
    return max(largest, 1.0) / 32000.0
