"""Blobs another marker's image may share: a merged blob's centroid lies off each
marker's ray, so a fill that places a marker on it is off by the merge.

Lowcost 303 (issue 27): a heel's blob merged with its ankle's, 1 px from each image,
placed the heel 14 mm off, with an expected error of 1 mm: with two partners the lengths
do not see it (their circle about the partners' axis meets a ray passed sideways along
it, a turn about that axis that no length measures).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs


def bridged(dense: NDArray, tracks: NDArray, fields: NDArray, reach: int) -> NDArray:
    """Positions (len(fields), len(tracks), 3) of ``tracks`` of ``dense`` at ``fields``:
    measured, or on the line between their samples on each side of a run of at most
    ``reach`` missing fields (a marker lost for a field or two is still there; its image
    merged into another's is often why it was lost); NaN elsewhere."""
    n = dense.shape[1]
    seen = np.isfinite(dense[tracks, :, 0])
    idx = np.arange(n)
    prev = np.maximum.accumulate(np.where(seen, idx, -1), axis=1)[:, fields].T
    nxt = np.minimum.accumulate(np.where(seen, idx, n)[:, ::-1], axis=1)[:, ::-1][:, fields].T
    ok = (prev >= 0) & (nxt < n) & (nxt - prev <= reach + 1)
    p, q = np.where(ok, prev, 0), np.where(ok, nxt, 0)
    w = ((fields[:, None] - p) / np.maximum(q - p, 1))[..., None]
    pts = dense[tracks[None], p] * (1 - w) + dense[tracks[None], q] * w
    return np.where(ok[..., None], pts, np.nan)


def shared_blobs(
    dense: NDArray,
    t: int,
    lo: int,
    ks: NDArray,
    rows: NDArray,
    spare: SpareBlobs,
    params: TrackingParams,
) -> NDArray[np.bool_]:
    """Which blobs ``rows`` (at gap offsets ``ks`` from ``lo``) another track of ``dense``
    (measured there, or within ``max_fill_gap_fields`` of its samples: :func:`bridged`)
    projects within ``ray_chain_gate_px`` of in that field: the image cannot tell whose
    they are, and a blob the marker's image merged into lies off its ray (lowcost 303: a
    heel's blob merged with its ankle's, 1 px from each, placed 14 mm off). With two
    partners the lengths do not see it: their circle about the partners' axis meets a
    ray passed sideways along it, a turn about that axis no length measures."""
    others = np.delete(np.arange(len(dense)), t)
    if rows.size == 0 or others.size == 0:
        return np.zeros(rows.size, dtype=bool)
    pts = bridged(dense, others, lo + ks, params.max_fill_gap_fields)  # (m, n_others, 3)
    cams = np.repeat(spare.camera[rows], others.size)
    with np.errstate(invalid="ignore"):
        uv = project_rows(spare.dlts, cams, pts.reshape(-1, 3)).reshape(*pts.shape[:2], 2)
        near = np.linalg.norm(uv - spare.uv_px[rows][:, None], axis=2) <= params.ray_chain_gate_px
    return np.any(near, axis=1)
