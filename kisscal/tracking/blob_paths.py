"""The marker's blobs followed in each camera's image through a gap, and how far a point
lies from a blob's ray.

From the marker's projection on each side of the gap, its blob is followed field by
field (:func:`follow_blobs`: constant-velocity prediction, the nearest free blob within
``ray_chain_gate_px`` plus half a field's motion, none when a second is less than twice
as far); the two directions must agree where both found a blob (:func:`chain_blobs`),
and where they part, the samples on the two sides are not ends of one path in the image
(:func:`parted`). These are the blobs the single-camera fills place on their rays
(:mod:`kisscal.tracking.raychain` and the fills after it).

References
----------
Hartley & Zisserman 2004 (rays of a projective camera).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import line_offsets, project_rows, ray_directions
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs


def follow_blobs(
    spare: SpareBlobs, cam: int, uv: NDArray, vel: NDArray, fields: NDArray, params: TrackingParams
) -> dict[int, int]:
    """The blob rows of camera ``cam`` that continue a path in the image from ``uv`` with
    velocity ``vel`` (px/field) over ``fields`` (consecutive, either direction); the
    path coasts over at most ``ray_chain_coast_fields`` fields without a blob."""
    found: dict[int, int] = {}
    missed = 0
    for f in fields.tolist():
        pred = uv + vel
        a, b = np.searchsorted(spare.field, [f, f + 1])
        rows = np.arange(a, b)
        rows = rows[spare.free[rows] & (spare.camera[rows] == cam)]
        dist = np.sort(np.linalg.norm(spare.uv_px[rows] - pred, axis=1))
        gate = params.ray_chain_gate_px + 0.5 * float(np.linalg.norm(vel))
        if dist.size and dist[0] <= gate and (dist.size == 1 or dist[1] >= 2.0 * dist[0]):
            row = int(rows[np.argmin(np.linalg.norm(spare.uv_px[rows] - pred, axis=1))])
            found[f] = row
            vel, uv, missed = spare.uv_px[row] - uv, spare.uv_px[row], 0
            continue
        uv, missed = pred, missed + 1
        if missed > params.ray_chain_coast_fields:
            break
    return found


def side_paths(
    target: NDArray, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams
) -> list[tuple[dict[int, int], dict[int, int]]]:
    """Per camera, the marker's blobs (field: spare row) in the gap [lo, hi) of
    ``target`` (n_fields, 3) followed in the image from the side before the gap and from
    the side after it (:func:`follow_blobs`, from the marker's projection there)."""
    out = []
    for cam in range(len(spare.dlts)):
        picks = []
        for edge, step, fields in (
            (lo - 1, -1, np.arange(lo, hi)),
            (hi, 1, np.arange(hi - 1, lo - 1, -1)),
        ):
            if not 0 <= edge < len(target):  # a run at the trial's start or end: one side
                picks.append({})
                continue
            ends = target[[edge, edge + step if 0 <= edge + step < len(target) else edge]]
            if not np.all(np.isfinite(ends[0])):
                picks.append({})
                continue
            ends = np.where(np.isfinite(ends), ends, ends[:1])
            uv = project_rows(spare.dlts, [cam, cam], ends)
            picks.append(follow_blobs(spare, cam, uv[0], uv[0] - uv[1], fields, params))
        out.append((picks[0], picks[1]))
    return out


def chain_blobs(
    target: NDArray, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Gap field offsets and spare rows of the marker's blobs in the gap [lo, hi) of
    ``target`` (n_fields, 3), followed in every camera from both sides (see module)."""
    ks, rows = [], []
    for fwd, bwd in side_paths(target, lo, hi, spare, params):
        for f in sorted(set(fwd) | set(bwd)):
            if f in fwd and f in bwd and fwd[f] != bwd[f]:
                continue
            ks.append(f - lo)
            rows.append(fwd.get(f, bwd.get(f)))
    return np.asarray(ks, dtype=np.int64), np.asarray(rows, dtype=np.int64)


def parted(target: NDArray, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams) -> bool:
    """Whether the marker's blobs followed in a camera's image from the two sides of the
    run [lo, hi) of ``target`` (n_fields, 3) part in some field (:func:`side_paths`):
    the two sides' samples are then not ends of one path in the image, and one of them
    may be another marker's (a sample of two merged images)."""
    return any(
        f in bwd and bwd[f] != row
        for fwd, bwd in side_paths(target, lo, hi, spare, params)
        for f, row in fwd.items()
    )


def one_camera_blobs(
    ks: NDArray[np.int64], rows: NDArray[np.int64], spare: SpareBlobs
) -> tuple[int, NDArray[np.int64], NDArray[np.int64]]:
    """The camera that sees most of a gap's blobs (``ks``, ``rows`` as
    :func:`chain_blobs`), and its blobs, the first of each field."""
    cam = int(np.bincount(spare.camera[rows]).argmax())
    keep = spare.camera[rows] == cam
    ks, first = np.unique(ks[keep], return_index=True)
    return cam, ks, rows[keep][first]


def off_rays(
    at: NDArray, ks: NDArray, o_ks: NDArray, o_rows: NDArray, spare: SpareBlobs, gate: float
) -> NDArray[np.int64]:
    """Gap offsets of ``ks`` (ascending) whose point ``at`` (m, 3) lies farther than
    ``gate`` mm from the ray of a blob of the marker there (offsets ``o_ks``, rows
    ``o_rows``; the point's own blob is on its ray): a second camera's blob disagrees,
    and one of the two is not the marker's alone (a merged blob's centroid lies off
    both markers' rays)."""
    if ks.size == 0:
        return np.zeros(0, dtype=np.int64)
    i = np.searchsorted(ks, o_ks)
    hit = (i < ks.size) & (ks[np.minimum(i, ks.size - 1)] == o_ks)
    i, o_rows = i[hit], o_rows[hit]
    return np.unique(ks[i[ray_miss_mm(spare, o_rows, at[i]) > gate]])


def ray_miss_mm(spare: SpareBlobs, rows: NDArray, xyz: NDArray) -> NDArray[np.float64]:
    """Distance (mm) of each lab point ``xyz`` (m, 3) from the ray of its blob ``rows``."""
    cam = spare.camera[rows]
    d = ray_directions(spare.dlts[cam], spare.uv_px[rows])
    return line_offsets(xyz - spare.centres[cam], d)[1]
