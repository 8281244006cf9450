"""Finding the wand: in each camera's image (before any calibration) or among 3D points.

In an image (:func:`find_wand_images`), a camera sees the wand in a field when exactly
as many moving blobs as the wand has markers lie on one line (within ``line_tol_px``)
with gaps in the proportions of the wand's (within ``ratio_tol`` of the image length;
perspective changes them a little). The marker order follows from the gaps when the
wand is not symmetric; a symmetric wand (two markers, or equal gaps) leaves the order
open, and the calibration settles it across cameras. Fields with extra moving blobs, or
with only some of the markers, are left out in that camera: a wand calibration has
hundreds of fields to spare.

Among 3D points of a calibrated rig (:func:`find_wand_points`), the wand is the set of
points at the wand's distances along one line (within ``match_tol_mm``), which no ghost
mimics; the order is the same for every camera.

Example
-------
>>> import numpy as np
>>> blobs = [np.array([[100.0, 50.0], [138.0, 50.0], [200.0, 50.0]])]  # 0, 190, 500 mm
>>> found = find_wand_images(blobs, [0.0, 190.0, 500.0])
>>> found.field.tolist(), found.ordered.tolist()
([0], [True])
>>> found.uv_px[0, :, 0].tolist()
[100.0, 138.0, 200.0]
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.bundle.params import DEFAULT_PARAMS, BundleParams


@dataclass(frozen=True)
class WandImages:
    """The wand found in one camera's fields.

    Attributes
    ----------
    field : ndarray of int, shape (n,)
        Fields in which the wand was found.
    uv_px : ndarray, shape (n, k, 2)
        Its marker images in ``markers_mm`` order (or reversed, where not ``ordered``).
    ordered : ndarray of bool, shape (n,)
        True where the gaps tell the ends apart.
    """

    field: NDArray[np.int64]
    uv_px: NDArray[np.float64]
    ordered: NDArray[np.bool_]

    def __len__(self) -> int:
        return len(self.field)


def wand_fractions(markers_mm: ArrayLike) -> NDArray[np.float64]:
    """Marker positions as fractions of the wand's length, ascending from 0 to 1."""
    s = np.sort(np.asarray(markers_mm, dtype=float))
    return (s - s[0]) / (s[-1] - s[0])


def find_wand_images(
    blobs_px: Sequence[ArrayLike], markers_mm: ArrayLike, params: BundleParams = DEFAULT_PARAMS
) -> WandImages:
    """The wand in each field of one camera (blobs already cleared of stationary ones).

    Parameters
    ----------
    blobs_px : sequence of (n_f, 2) arrays
        Blob centroids of every field.
    markers_mm : array_like
        The wand's marker positions along its axis (``[wand] markers_mm``).
    params : BundleParams
        ``line_tol_px`` and ``ratio_tol``.

    Returns
    -------
    WandImages
    """
    frac = wand_fractions(markers_mm)
    k = len(frac)
    fields = np.array([i for i, b in enumerate(blobs_px) if len(b) == k], dtype=np.int64)
    if len(fields) == 0:
        return WandImages(np.zeros(0, np.int64), np.zeros((0, k, 2)), np.zeros(0, bool))
    uv = np.stack([np.asarray(blobs_px[i], dtype=float).reshape(k, 2) for i in fields])
    dist = np.linalg.norm(uv[:, :, None] - uv[:, None], axis=-1)
    flat = dist.reshape(len(uv), -1).argmax(axis=1)
    a, b = np.divmod(flat, k)
    rows = np.arange(len(uv))
    end_a, end_b = uv[rows, a], uv[rows, b]
    length = np.linalg.norm(end_b - end_a, axis=1)
    axis = (end_b - end_a) / np.maximum(length, 1e-12)[:, None]
    rel = uv - end_a[:, None]
    along = np.einsum("nkj,nj->nk", rel, axis)
    across = np.abs(rel[..., 0] * axis[:, None, 1] - rel[..., 1] * axis[:, None, 0])
    order = np.argsort(along, axis=1)
    uv = np.take_along_axis(uv, order[..., None], axis=1)
    t = np.take_along_axis(along, order, axis=1) / np.maximum(length, 1e-12)[:, None]
    forward = np.abs(t - frac).max(axis=1)
    backward = np.abs(t - (1.0 - frac[::-1])).max(axis=1)
    straight = across.max(axis=1) <= params.line_tol_px
    fits = np.minimum(forward, backward) <= params.ratio_tol
    ok = straight & fits & (length > 0)
    reverse = backward < forward
    uv[reverse] = uv[reverse, ::-1]
    ordered = np.abs(forward - backward) > params.ratio_tol
    uv = uv[:, _given_order(markers_mm)]
    return WandImages(fields[ok], uv[ok], ordered[ok])


def _given_order(markers_mm: ArrayLike) -> NDArray[np.int64]:
    """Columns in ascending-position order -> columns in the order ``markers_mm`` lists."""
    return np.argsort(np.argsort(np.asarray(markers_mm, dtype=float)))


@dataclass(frozen=True)
class WandPoints:
    """The wand found among the 3D points of a trial.

    Attributes
    ----------
    field : ndarray of int, shape (n,)
        Fields in which the wand was found (one wand per field).
    point : ndarray of int, shape (n, k)
        Index of each marker's 3D point, in ``markers_mm`` order.
    """

    field: NDArray[np.int64]
    point: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.field)


def find_wand_points(
    field: ArrayLike,
    xyz_mm: ArrayLike,
    markers_mm: ArrayLike,
    tol_mm: float = DEFAULT_PARAMS.match_tol_mm,
) -> WandPoints:
    """The wand among 3D points: ends at the wand's length, inner markers where they belong.

    Parameters
    ----------
    field : array_like of int, shape (n,)
        Field of each point, ascending.
    xyz_mm : array_like, shape (n, 3)
        Reconstructed points.
    markers_mm : array_like
        Marker positions along the wand.
    tol_mm : float
        Largest error of the end-to-end distance and of each inner marker's position.

    Returns
    -------
    WandPoints
        Fields with exactly one such set of points.
    """
    field = np.asarray(field, dtype=np.int64)
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    s = np.asarray(markers_mm, dtype=float)
    frac = wand_fractions(s)
    length = float(s.max() - s.min())
    if len(field) < len(s):
        return WandPoints(np.zeros(0, np.int64), np.zeros((0, len(s)), np.int64))
    first, second = pairs_within_fields(field)
    gap = np.linalg.norm(xyz[second] - xyz[first], axis=1)
    ok = np.abs(gap - length) <= tol_mm
    first, second = first[ok], second[ok]
    members = [first]
    for f in frac[1:-1]:
        guess = xyz[first] + f * (xyz[second] - xyz[first])
        nearest, d = _nearest_in_field(field, xyz, field[first], guess)
        ok = d <= tol_mm
        members = [m[ok] for m in members]
        first, second, guess = first[ok], second[ok], guess[ok]
        members.append(nearest[ok])
    members.append(second)
    point = np.column_stack(members)
    f_of = field[point[:, 0]]
    # a symmetric wand passes both ways round: keep one; two distinct wands: drop the field
    symmetric = np.all(np.abs(frac - (1.0 - frac[::-1])) <= 1e-9)
    canonical = point[:, 0] < point[:, -1] if symmetric else np.ones(len(point), bool)
    point, f_of = point[canonical][:, _given_order(s)], f_of[canonical]
    uniq, count = np.unique(f_of, return_counts=True)
    single = np.isin(f_of, uniq[count == 1])
    return WandPoints(f_of[single], point[single])


def pairs_within_fields(field: NDArray[np.int64]) -> tuple[NDArray, NDArray]:
    """Every ordered pair (i, j), i != j, of rows in the same field."""
    starts = np.r_[0, np.flatnonzero(np.diff(field)) + 1]
    counts = np.diff(np.r_[starts, len(field)])
    per_row = counts[np.repeat(np.arange(len(counts)), counts)]
    i = np.repeat(np.arange(len(field)), per_row)
    first_of_row = np.repeat(starts, counts)
    offset = np.arange(len(i)) - np.repeat(np.cumsum(per_row) - per_row, per_row)
    j = np.repeat(first_of_row, per_row) + offset
    keep = i != j
    return i[keep], j[keep]


def _nearest_in_field(
    field: NDArray[np.int64],
    xyz: NDArray[np.float64],
    where: NDArray[np.int64],
    guess: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """For each guess, the nearest point of field ``where`` and its distance."""
    starts = np.r_[0, np.flatnonzero(np.diff(field)) + 1]
    counts = np.diff(np.r_[starts, len(field)])
    fields = field[starts]
    slot = np.searchsorted(fields, where)
    widest = int(counts.max()) if len(counts) else 0
    cand = starts[slot][:, None] + np.arange(widest)[None, :]
    valid = np.arange(widest)[None, :] < counts[slot][:, None]
    cand = np.where(valid, cand, 0)
    d = np.linalg.norm(xyz[cand] - guess[:, None, :], axis=2)
    d = np.where(valid, d, np.inf)
    best = d.argmin(axis=1)
    return cand[np.arange(len(cand)), best], d[np.arange(len(cand)), best]
