"""The point samples of a C3D file decoded from the layout its header gives.

A C3D file's data section is laid out by its header: points per frame, analog words per
frame, the first and last frame, the scale (negative: floats) and the first data block.
Most files say the same in their parameters (``POINT:USED``, ``ANALOG:USED`` times the
analog samples per frame), and readers such as ezc3d lay the data out from those. Some
writers' parameters disagree with the header (a Motion Analysis EVaRT file with 1000 Hz
analog at 60 Hz: 17 samples per frame in the header, 16.67 by the rates; a Kyowa Dengyo
file whose ``POINT:USED`` counts one point more than the header and the data; a BTS
file with no ``ANALOG`` parameters but analog words in every frame): read by the
parameters, every frame after the first is shifted and the markers come out as noise.
Where the two disagree, the layout that fills the file's data section to its last
512-byte block is the one the writer used (a MotionMonitor file's header counts 16
analog words a frame where its parameters and its size say 112: there the parameters
hold); :func:`header_holds` tells, :func:`read_points_by_header` decodes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

#: Byte order of the 16-bit words and the float format of each processor type.
_INT = {"Intel": "<i2", "DEC": "<i2", "MIPS": ">i2"}
_FLOAT = {"Intel": "<f4", "DEC": "<f4", "MIPS": ">f4"}


def dec_floats(raw: NDArray[np.uint8]) -> NDArray[np.float32]:
    """DEC (VAX F) floats, 4 bytes each, as IEEE values: the two 16-bit halves swapped
    and the value divided by 4 (the exponent bias differs by 2)."""
    b = np.asarray(raw, dtype=np.uint8).reshape(-1, 4)
    swapped = np.ascontiguousarray(b[:, [2, 3, 0, 1]]).view("<f4").ravel()
    return (swapped / 4.0).astype(np.float32)


def _floats(raw: bytes, processor: str) -> NDArray[np.float32]:
    if processor == "DEC":
        return dec_floats(np.frombuffer(raw, dtype=np.uint8))
    return np.frombuffer(raw, dtype=_FLOAT[processor]).astype(np.float32)


def header_layout(path: Path, processor: str) -> dict[str, float]:
    """The header's data layout: ``points``, ``analog_words`` (per frame), ``first`` and
    ``last`` frame, ``scale`` and the first data ``block`` (C3D.org 2023, the header)."""
    with Path(path).open("rb") as fh:
        head = fh.read(512)
    words = np.frombuffer(head[:24], dtype=_INT[processor].replace("i", "u"))
    return {
        "points": int(words[1]),
        "analog_words": int(words[2]),
        "first": int(words[3]),
        "last": int(words[4]),
        "scale": float(_floats(head[12:16], processor)[0]),
        "block": int(words[8]),
    }


def read_points_by_header(
    path: Path, processor: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Positions (n_frames, n_points, 3) in the file's units, the fourth word of each
    sample (negative: invalid) and the first frame, decoded from the header's layout.

    References
    ----------
    C3D.org (2023). The C3D file format user guide: the header, 3D point data in integer
    and floating-point formats, processor types.
    """
    lay = header_layout(path, processor)
    n_points, n_analog = lay["points"], lay["analog_words"]
    n_frames = max(int(lay["last"] - lay["first"] + 1), 0)
    as_float = lay["scale"] < 0
    size = 4 if as_float else 2
    per_frame = 4 * n_points + n_analog
    with Path(path).open("rb") as fh:
        fh.seek((max(int(lay["block"]), 1) - 1) * 512)
        raw = fh.read(size * per_frame * n_frames)
    n_frames = min(n_frames, len(raw) // max(size * per_frame, 1))
    raw = raw[: size * per_frame * n_frames]
    if as_float:
        values = _floats(raw, processor).astype(float)
    else:
        values = np.frombuffer(raw, dtype=_INT[processor]).astype(float)
    frames = values.reshape(n_frames, per_frame)[:, : 4 * n_points].reshape(n_frames, n_points, 4)
    xyz = frames[..., :3] * (1.0 if as_float else abs(lay["scale"]))
    return xyz, frames[..., 3], int(lay["first"])


def parameter_layout(params: dict[tuple[str, str], list], rate: float) -> tuple[int, int]:
    """Points and analog words per frame as the parameters give them (``POINT:USED``;
    ``ANALOG:USED`` times the whole analog samples per point frame, ``ANALOG:RATE`` over
    the point rate, as ezc3d lays them out)."""

    def first(group: str, name: str, default: float) -> float:
        values = params.get((group, name), [])
        try:
            return float(values[0]) if len(values) else default
        except (TypeError, ValueError):
            return default

    points = int(first("POINT", "USED", 0))
    channels = int(first("ANALOG", "USED", 0))
    per_frame = first("ANALOG", "RATE", rate) / rate if rate > 0 and channels else 0.0
    return points, channels * int(np.floor(per_frame + 1e-6))


def _data_end(lay: dict[str, float], points: int, analog_words: int) -> int:
    """Where the data section ends (bytes) with ``points`` and ``analog_words`` a frame."""
    size = 4 if lay["scale"] < 0 else 2
    frames = max(int(lay["last"] - lay["first"] + 1), 0)
    return int((max(lay["block"], 1) - 1) * 512 + frames * (4 * points + analog_words) * size)


def header_rate(path: Path, processor: str) -> float:
    """The header's frame rate (words 11-12, a float in every format)."""
    with Path(path).open("rb") as fh:
        head = fh.read(24)
    return float(_floats(head[20:24], processor)[0]) if len(head) == 24 else 0.0


def header_fits(path: Path, processor: str) -> bool:
    """Whether the header's layout (points and analog words a frame, frames, format)
    fills the file's data section to its last 512-byte block: the header alone then
    describes the data, whatever the parameter section holds."""
    lay = header_layout(path, processor)
    whole = lay["points"] > 0 and lay["last"] >= lay["first"]
    return whole and _ends_last_block(path, _data_end(lay, lay["points"], lay["analog_words"]))


def _ends_last_block(path: Path, end: int) -> bool:
    size = Path(path).stat().st_size
    return end <= size and size - end < 512


def header_holds(
    path: Path, processor: str, params: dict[tuple[str, str], list], rate: float
) -> bool:
    """Whether the header's layout differs from the parameters' and is the one the file's
    size bears out: its data ends in the file's last 512-byte block, the parameters'
    does not."""
    lay = header_layout(path, processor)
    by_params = parameter_layout(params, rate)
    if (lay["points"], lay["analog_words"]) == by_params:
        return False
    return _ends_last_block(
        path, _data_end(lay, lay["points"], lay["analog_words"])
    ) and not _ends_last_block(path, _data_end(lay, *by_params))
