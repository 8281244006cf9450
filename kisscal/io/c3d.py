"""Reading marker trajectories from C3D files (with ezc3d)."""

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
    units = str(params.get("UNITS", {}).get("value", ["mm"])[0]).strip().lower()
    scale = {"mm": 1.0, "m": 1000.0, "cm": 10.0}.get(units)
    if scale is None:
        raise KisscalError(f"{path}: unsupported point units {units!r}")
    points = c3d["data"]["points"][:3].transpose(2, 1, 0) * scale  # (frames, points, 3)
    residuals = c3d["data"]["meta_points"]["residuals"][0].T
    points = np.where((residuals < 0)[..., None], np.nan, points)
    rate = float(c3d["header"]["points"]["frame_rate"])
    return labels[: points.shape[1]], points.astype(float), rate
