"""The lab frame from an axes object: recognise its markers in 3D, fit the rigid motion.

A wand calibration without surveyed points knows the cameras up to a rigid motion; an
object of known shape (an "L-frame" of four or more markers, not all on one line) fixes
it, as docs/methods.md, "Wand calibration", tells. The scale is kept from the wand; the
object's scale is returned as a check of the wand length.

References
----------
Arun, K. S., Huang, T. S., & Blostein, S. D. (1987). Least-squares fitting of two 3-D
point sets. IEEE PAMI 9(5).
Umeyama, S. (1991). Least-squares estimation of transformation parameters between two
point patterns. IEEE PAMI 13(4).

Example
-------
>>> import numpy as np
>>> frame = np.array([[0.0, 0, 0], [400, 0, 0], [0, 300, 0], [150, 0, 0]])
>>> seen = np.array([[900.0, 0, 0], [10, 20, 5], [10, 320, 5], [410, 20, 5], [160, 20, 5]])
>>> match = recognise_object(seen, frame)
>>> match.index.tolist(), round(match.scale, 6)
([1, 3, 2, 4], 1.0)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.errors import EstimationFailed


@dataclass(frozen=True)
class ObjectMatch:
    """Reconstructed points recognised as the markers of a known object.

    Attributes
    ----------
    index : ndarray of int, shape (n,)
        The reconstructed point of each object marker.
    scale : float
        Object size / reconstructed size (1 when the wand and the object agree).
    rms_mm : float
        RMS distance of the object markers from the fitted points (mm, in object units).
    rotation : ndarray, shape (3, 3)
    shift_mm : ndarray, shape (3,)
        The rigid motion ``X_lab = rotation X + shift_mm`` (scale not applied).
    """

    index: NDArray[np.int64]
    scale: float
    rms_mm: float
    rotation: NDArray[np.float64]
    shift_mm: NDArray[np.float64]


def similarity(
    source: ArrayLike, target: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """``(rotation, shift, scale)`` minimising ``|scale (rotation source + shift) - target|``.

    The rigid part is fitted with the source's own scale (Arun et al. 1987); ``scale`` is
    the least-squares ratio of target to source sizes (Umeyama 1991).
    """
    a = np.asarray(source, dtype=float)
    b = np.asarray(target, dtype=float)
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    H = (a - ma).T @ (b - mb)
    U, S, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    scale = float(np.trace(np.diag(S) @ D) / np.sum((a - ma) ** 2))
    return R, mb / scale - R @ ma, scale


def recognise_object(xyz_mm: ArrayLike, object_mm: ArrayLike) -> ObjectMatch:
    """Find the object's markers among reconstructed points by their mutual distances.

    Parameters
    ----------
    xyz_mm : array_like, shape (m, 3)
        Reconstructed points (the object's markers and possibly others), m >= n.
    object_mm : array_like, shape (n, 3)
        The object's markers (``[axes] points_mm``), n >= 4.

    Raises
    ------
    KisscalError
        Too few points, no assignment whose mutual distances differ from the object's
        by 5 % RMS or less (after the best common scale), or two that fit equally well
        (a symmetric object).
    """
    pts = as_points(xyz_mm, 3, "xyz_mm")
    obj = as_points(object_mm, 3, "object_mm")
    n = len(obj)
    if len(pts) < n:
        raise EstimationFailed(
            f"axes: {len(pts)} markers reconstructed, the axes object has {n}; "
            "every axes marker must be seen by two cameras"
        )
    d_obj = np.linalg.norm(obj[:, None] - obj[None], axis=2)
    d_pts = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    tuples = _candidates(d_pts, d_obj)
    if len(tuples) == 0:
        raise EstimationFailed(
            f"axes: no {n} reconstructed markers have the axes object's shape; "
            "check [axes] points_mm"
        )
    d = d_pts[tuples[:, :, None], tuples[:, None, :]]
    iu = np.triu_indices(n, 1)
    ratio = d[:, iu[0], iu[1]] / d_obj[iu]
    scale = np.median(ratio, axis=1)
    err = np.sqrt(np.mean((ratio / scale[:, None] - 1.0) ** 2, axis=1))
    order = np.argsort(err)
    best = order[0]
    runner = float(err[order[1]]) if len(order) > 1 else np.inf
    if err[best] > 0.05:
        raise EstimationFailed(
            f"axes: no {n} reconstructed markers have the axes object's shape (best relative "
            f"distance error {err[best]:.1%}); check [axes] points_mm"
        )
    if runner <= 2.0 * err[best] + 1e-3:
        raise EstimationFailed(
            "axes: the axes object's markers can be matched two ways (it is symmetric); "
            "use an object whose marker distances are all different"
        )
    index = tuples[best]
    R, _, s = similarity(pts[index], obj)
    shift = obj.mean(axis=0) - R @ pts[index].mean(axis=0)
    fitted = pts[index] @ R.T + shift
    rms = float(np.sqrt(np.mean(np.sum((fitted - obj) ** 2, axis=1))))
    return ObjectMatch(index, s, rms, R, shift)


def _candidates(
    d_pts: NDArray[np.float64], d_obj: NDArray[np.float64], widest: float = 1.6
) -> NDArray[np.int64]:
    """Assignments of points to object markers whose distances agree within a factor.

    Built marker by marker: an assignment grows only by points whose distances to the
    points already chosen are within ``widest`` of the object's (both ways), which keeps
    the search small whatever the number of ghosts.
    """
    m, n = len(d_pts), len(d_obj)
    out = np.arange(m)[:, None]
    for level in range(1, n):
        grown = np.column_stack([np.repeat(out, m, axis=0), np.tile(np.arange(m), len(out))])
        new = grown[:, -1]
        fresh = np.all(grown[:, :-1] != new[:, None], axis=1)
        ratio = d_pts[grown[:, :-1], new[:, None]] / d_obj[np.arange(level), level]
        ok = fresh & np.all((ratio < widest) & (ratio > 1.0 / widest), axis=1)
        out = grown[ok]
    return out


def average_static(frames_px: Sequence[ArrayLike], radius_px: float = 1.5) -> NDArray[np.float64]:
    """Blobs of a static scene averaged over its frames, shape (n, 2).

    A blob of the first frame is kept when blobs lie within ``radius_px`` of it in at
    least half the frames; its position is their mean. Blobs that flicker (noise pixels)
    are dropped.
    """
    frames = [as_points(f, 2, "a frame of frames_px") for f in frames_px]
    if not frames or not len(frames[0]):
        return np.zeros((0, 2))
    seeds = frames[0]
    total = np.zeros_like(seeds)
    count = np.zeros(len(seeds))
    for f in frames:
        if not len(f):
            continue
        d = np.linalg.norm(seeds[:, None] - f[None], axis=2)
        near = d.argmin(axis=1)
        ok = d[np.arange(len(seeds)), near] <= radius_px
        total[ok] += f[near[ok]]
        count[ok] += 1
    keep = count >= 0.5 * len(frames)
    return total[keep] / count[keep, None]
