"""The version-1 files of a camera calibrated with Brown lens terms (wand, target routes).

The lens is folded into the 30-coefficient linearisation polynomial, fitted to the
grid's linearisation followed by the lens inverse, weighted on the image positions the
camera was calibrated from (without a grid, to the lens inverse alone, with the largest
errors spread evenly so that the image corners hold too). A polynomial
follows a lens model only to a few hundredths of a pixel, which at a few metres is a
tenth of a millimetre; so the DLT is then fitted again, linearly, to the calibration's
own 3D points and their images through the written polynomial (it starts out as the
distortion-free camera ``K [R | t]``), which takes up what the polynomial missed, as
the rods' DLT does for the grid's polynomial. The grid's own linearisation document is
kept inside the new one (``refined.grid_fit``) so that a later route can put it back.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kisscal.camera import LENS_TERMS, Camera, camera_linearisation
from kisscal.dlt import DltParams, correct_lens, project, solve_dlt
from kisscal.dlt.calibrate import dlt_result
from kisscal.dlt.camera import hatze_violation
from kisscal.grid import Linearisation, apply_linearisation, invert_linearisation
from kisscal.io.config import CameraConfig
from kisscal.io.dltfiles import write_dlt_json
from kisscal.io.files import write_json
from kisscal.io.linearisation import (
    linearisation_from_dict,
    read_linearisation_doc,
    refined_by,
    write_linearisation,
)
from kisscal.session.routes import RouteInputs
from kisscal.target.match import is_planar


def grid_document(path: Path, has_grid: bool) -> dict[str, Any] | None:
    """The grid's own linearisation document of a camera (None without a grid)."""
    if not has_grid:
        return None
    doc = read_linearisation_doc(path)
    if doc is not None and refined_by(doc) is not None:
        return doc["refined"].get("grid_fit")
    return doc


def _fold_lens(
    lin_path: Path,
    cfg: CameraConfig,
    camera: Camera,
    route: str,
    before: Linearisation | None,
    grid_doc: dict[str, Any] | None,
    points: tuple[NDArray, NDArray, NDArray, Sequence[str]],
    dlt: DltParams,
) -> tuple[NDArray, NDArray]:
    """The lens folded into a written polynomial; the points through it and the DLT
    refitted to them."""
    xyz, uv, _, _ = points
    raw = invert_linearisation(before, uv) if before is not None and len(uv) else uv
    # without a grid the polynomial is the whole lens: it must hold to the image corners
    lin, fit_max = camera_linearisation(camera, cfg.size_px, before, raw, minimax=before is None)
    quality = before.quality if before is not None else None
    lin = Linearisation(lin.center_px, lin.scale_px, lin.x, lin.y, quality)
    refined = {
        "by": route,
        "lens_model": "Brown (OpenCV k1 k2 p1 p2 k3) on "
        + ("the grid's linearised pixels" if before is not None else "raw pixels"),
        "lens": {t: float(v) for t, v in zip(LENS_TERMS, camera.lens, strict=True)},
        "fit_max_px": fit_max,
        "grid_fit": grid_doc,
    }
    write_linearisation(lin_path, lin, cfg.id, refined=refined)
    written = apply_linearisation(lin, raw)
    return written, written_dlt(camera, xyz, written, dlt, cfg.id)


def written_dlt(
    camera: Camera, xyz: NDArray, ideal_px: NDArray, dlt: DltParams, name: str
) -> NDArray[np.float64]:
    """The DLT written for ``camera`` fitted with its lens to ``xyz`` and ``ideal_px`` (the
    points with the lens removed): refitted to them when they are not flat (a DLT's
    skew and aspect follow a sensor the camera model has no term for), else its own."""
    if len(xyz) >= dlt.min_points and not is_planar(xyz, dlt):
        return solve_dlt(xyz, ideal_px, dlt, camera=name)
    return camera.dlt


def write_lens_camera(
    inputs: RouteInputs,
    cfg: CameraConfig,
    camera: Camera,
    route: str,
    points: tuple[NDArray, NDArray, NDArray, Sequence[str]],
    iterations: int,
    extra: Mapping[str, Any] | None = None,
    *,
    kinds: str | Sequence[str],
) -> float:
    """Write ``linearisation/<camera>.json`` and ``dlt/<camera>.json``; the written DLT's
    RMS (px) on the points.

    ``points`` are the observations the camera was fitted to: lab mm, image px (the lens
    model's coordinates), residuals px and labels; the file lists them through the
    written polynomial, with their residuals under the written DLT, and what each is
    (``kinds``, one for all or one per point: :data:`kisscal.io.dltfiles.POINT_KINDS`).
    """
    lin_path = inputs.store.linearisation_path(cfg.id)
    grid_doc = grid_document(lin_path, inputs.config.grid is not None)
    before = linearisation_from_dict(grid_doc, str(lin_path)) if grid_doc else None
    xyz, uv, _, labels = points
    kolahi = None
    if before is not None and not np.any(camera.lens):
        # the grid's polynomial kept as it is: the camera is exactly its DLT on it, with
        # Kolahi's terms when it carries them (resected)
        write_json(lin_path, grid_doc)
        written, L, kolahi = uv, camera.dlt, camera.kolahi
    else:
        written, L = _fold_lens(
            lin_path, cfg, camera, route, before, grid_doc, points, inputs.params.dlt
        )
    res = correct_lens(L, kolahi, written) - project(L, xyz)
    result = dlt_result(L, route, kolahi, res, hatze_violation(camera.dlt), iterations)
    path = inputs.store.dlt_path(cfg.id)
    write_dlt_json(path, cfg.id, result, xyz, written, labels, extra, kinds)
    return float(result.rms_px)
