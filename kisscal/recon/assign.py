"""Steps both matching strategies share: checking the 2D table, solving and accepting a
candidate marker, extending it by the blobs near its projections, and finishing a trial's
markers (merged, re-triangulated, split or dropped over the residual limit)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.dlt.model import project_rows
from kisscal.errors import InputError
from kisscal.recon.group import (
    Solved,
    merge_groups,
    residual_limit_px,
    split_or_drop,
    triangulate_markers,
)
from kisscal.recon.params import ReconParams


def check_table(
    field: ArrayLike, camera: ArrayLike, uv: ArrayLike, n_cameras: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    field = np.asarray(field, dtype=np.int64).ravel()
    camera = np.asarray(camera, dtype=np.int64).ravel()
    uv = as_points(uv, 2, "2D table: uv")
    if not (len(field) == len(camera) == len(uv)):
        raise InputError("2D table: field, camera and uv must have one row per blob")
    if len(camera) and (camera.min() < 0 or camera.max() >= n_cameras):
        raise InputError(f"2D table: camera index outside 0..{n_cameras - 1}")
    if not np.all(np.isfinite(uv)):
        raise InputError("2D table: pixel coordinates contain NaN or inf")
    return field, camera, uv


def solve_one(
    L: NDArray[np.float64], uv: NDArray[np.float64], reweight_iterations: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One point from its rows of DLT parameters ``L`` (n, 11) and pixels ``uv`` (n, 2):
    the eq. 10 least-squares solution (+ reweighted steps) and each observation's residual.
    The per-field strategy calls this thousands of times, so it avoids batch overheads."""
    lower = L[:, 8:11]
    A = np.concatenate([L[:, 0:3] - uv[:, :1] * lower, L[:, 4:7] - uv[:, 1:] * lower])
    b = np.concatenate([uv[:, 0] - L[:, 3], uv[:, 1] - L[:, 7]])
    w = np.ones(len(b))
    for _ in range(reweight_iterations + 1):
        xyz = np.linalg.lstsq(A * w[:, None], b * w, rcond=None)[0]
        den = lower @ xyz + 1.0
        w = np.concatenate([1.0 / den, 1.0 / den])
    res = (L[:, [0, 1, 2, 4, 5, 6]].reshape(-1, 2, 3) @ xyz + L[:, [3, 7]]) / den[:, None] - uv
    return xyz, np.hypot(res[:, 0], res[:, 1])


def accept(
    rows: list[int],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
    min_cameras: int,
) -> list[int]:
    """Observations of one marker after dropping worst ones until ``rms_px`` is in bounds."""
    rows = list(rows)
    while len(rows) >= min_cameras:
        r = np.asarray(rows)
        _, res = solve_one(dlts[camera[r]], uv[r], params.reweight_iterations)
        if np.sqrt(np.mean(res**2)) <= params.max_rms_px:
            return rows
        rows.pop(int(np.argmax(res)))
    return []


def extend(
    members: dict[int, int],
    xyz: NDArray[np.float64],
    free_rows: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    radius_px: float,
) -> list[int]:
    """Add, in each camera not yet in ``members``, the free blob nearest to the marker's
    projection if it lies within ``radius_px`` (Shafiq et al. 2001, 4.1, extension)."""
    rows = list(members.values())
    for k in np.unique(camera[free_rows]):
        if int(k) in members:
            continue
        cand = free_rows[camera[free_rows] == k]
        d = np.linalg.norm(uv[cand] - project_rows(dlts, camera[cand], xyz[None, :]), axis=1)
        best = int(np.argmin(d))
        if d[best] <= radius_px:
            rows.append(int(cand[best]))
    return rows


def finish(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
    solved: Solved | None = None,
) -> NDArray[np.int64]:
    """3D grouping, then the residual limit: split or drop markers with fewer than three
    observations or over the limit. ``solved``: markers of this table
    solved before (:class:`~kisscal.recon.group.Solved`)."""
    marker = merge_groups(
        marker,
        field,
        camera,
        uv,
        dlts,
        params.group_radius_mm,
        params.max_rms_px,
        params.reweight_iterations,
        solved,
    )
    if not (marker >= 0).any():
        return marker
    tri = triangulate_markers(marker, camera, uv, dlts, params.reweight_iterations, solved)
    return split_or_drop(
        marker,
        field,
        camera,
        uv,
        dlts,
        residual_limit_px(tri.rms_px, params),
        3,
        params.reweight_iterations,
        solved,
    )
