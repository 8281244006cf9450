"""C3D files: reading marker trajectories (with ezc3d), and the parts of writing that ezc3d
does not do as the C3D standard asks (the per-sample residual and camera mask word)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import KisscalError


def read_c3d_points(path: Path) -> tuple[tuple[str, ...], NDArray[np.float64], float]:
    """Point labels, positions (n_frames, n_points, 3) in mm with NaN where invalid, and rate.

    Samples flagged invalid by the recording system (negative residual) become NaN.
    """
    import ezc3d

    path = Path(path)
    if not path.is_file():
        raise KisscalError(f"{path}: C3D file not found")
    try:
        c3d = ezc3d.c3d(str(path))
    except Exception as exc:  # ezc3d raises plain exceptions on corrupt files
        raise KisscalError(f"{path}: not a readable C3D file ({exc})") from None
    params = c3d["parameters"]["POINT"]
    labels = tuple(str(s).strip() for s in params["LABELS"]["value"])
    # POINT:UNITS may be missing or empty: millimetres, the C3D default
    units = str((list(params.get("UNITS", {}).get("value", [])) or ["mm"])[0]).strip().lower()
    units = units or "mm"
    scale = {"mm": 1.0, "m": 1000.0, "cm": 10.0}.get(units)
    if scale is None:
        raise KisscalError(f"{path}: unsupported point units {units!r}")
    points = c3d["data"]["points"][:3].transpose(2, 1, 0) * scale  # (frames, points, 3)
    residuals = c3d["data"]["meta_points"]["residuals"][0].T
    points = np.where((residuals < 0)[..., None], np.nan, points)
    rate = float(c3d["header"]["points"]["frame_rate"])
    return labels[: points.shape[1]], points.astype(float), rate


# ------------------------------------------------------------------ writing: per-sample words

#: Cameras a C3D camera mask can name: 7 bits (the word's top bit is the residual's sign).
C3D_MASK_CAMERAS = 7


def sample_words(
    status: NDArray[np.int8],
    rms_px: NDArray[np.float64],
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
    rms_px : (S,) float
        Reconstruction residual of the sample (NaN when unknown: stored as the smallest
        positive residual).
    cameras : (S, n_cameras) bool
        Cameras the sample was seen by.
    scale : float
        ``|POINT:SCALE|``.

    References
    ----------
    C3D.org (2023). The C3D file format user guide: 3D point data, integer and
    floating-point formats (camera mask in the high byte, residual in the low byte).
    """
    from kisscal.tracking.tracks import MEASURED

    measured = np.asarray(status) == MEASURED
    steps = np.nan_to_num(np.asarray(rms_px, dtype=float) / scale, nan=1.0, posinf=255.0)
    residual = np.clip(np.round(steps), 1, 255).astype(np.int64)
    bits = np.asarray(cameras, dtype=bool)[:, :C3D_MASK_CAMERAS]
    mask = (bits * (1 << np.arange(bits.shape[1]))).sum(axis=1).astype(np.int64)
    return np.where(measured, (mask << 8) | residual, 0).astype(np.float32)


def patch_sample_words(path: Path, words: NDArray[np.float32], scale: float) -> None:
    """Set the fourth word of every point sample of a float C3D file, in place, and the
    header's scale factor to ``-scale`` (POINT:SCALE's value).

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
            raise KisscalError(f"{path}: not the float C3D layout kisscal writes")
        head[6:8] = np.array([-scale], dtype="<f4").view("<i2")
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
