"""The body at reconstruction: two-camera points that keep a segment's rigid distances.

A two-camera pair seen for one to three fields, with no third view, has no trajectory to
continue (:mod:`kisscal.recon.pairs` needs four positions): it is as likely the crossing
of two markers' rays as a marker. The marker set says more. The markers of one segment
keep fixed distances (three on the pelvis, the knee, tibia and ankle on the shank, the
ankle, heel and toe on the foot): a true point of such a marker lies at the template's
distances from two other points of its field that lie at the template's distance from
each other; the crossing of two rays lands there only by chance. A pair whose blobs no
other such pair wants is taken on that evidence (Cappozzo et al. 1995: markers of one
segment as a rigid cluster; Küçük 2005, 3.4, used the body's model to resolve what the
views leave open).

:class:`RigidTriangles` holds the triangles of markers that the marker set's segments
link pairwise; :func:`body_error` measures how well points fit one of them;
:func:`body_pairs` takes the pairs that fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import InputError
from kisscal.recon.params import ReconParams


@dataclass(frozen=True)
class RigidTriangles:
    """Triangles (i, j, k) of markers linked pairwise by segments, from marker i: the
    distances ``d_ij`` and ``d_ik`` (mm, (s,)) and ``d_jk`` between the other two."""

    d_ij: NDArray[np.float64]
    d_ik: NDArray[np.float64]
    d_jk: NDArray[np.float64]

    @classmethod
    def from_marker_set(
        cls, names: tuple[str, ...], template_mm: ArrayLike, segments: tuple
    ) -> RigidTriangles:
        """The triangles of a marker set: ``names`` (n,), ``template_mm`` (n, 3) the
        markers' positions in any frame, ``segments`` pairs of names that a rigid body
        links (as the tracking stage takes them).

        Examples
        --------
        >>> t = RigidTriangles.from_marker_set(
        ...     ("A", "B", "C"), [[0, 0, 0], [3, 0, 0], [0, 4, 0]],
        ...     (("A", "B"), ("B", "C"), ("A", "C")))
        >>> t.d_ij.tolist(), t.d_ik.tolist(), t.d_jk.tolist()
        ([3.0, 3.0, 4.0], [4.0, 5.0, 5.0], [5.0, 4.0, 3.0])
        """
        template = np.asarray(template_mm, dtype=float)
        if template.shape != (len(names), 3) or not np.all(np.isfinite(template)):
            raise InputError(
                f"body template: {template.shape} finite positions for {len(names)} names"
            )
        index = {name: i for i, name in enumerate(names)}
        unknown = sorted({n for s in segments for n in s} - set(index))
        if unknown:
            raise InputError(f"body template: segments name unknown markers {unknown}")
        linked = {frozenset((index[a], index[b])) for a, b in segments if a != b}
        rows = []
        for i in range(len(names)):
            near = sorted(j for e in linked if i in e for j in e if j != i)
            rows += [(i, j, k) for j, k in combinations(near, 2) if {j, k} in linked]
        ijk = np.array(rows, dtype=np.int64).reshape(-1, 3)
        d = [
            np.linalg.norm(template[ijk[:, p]] - template[ijk[:, q]], axis=1)
            for p, q in ((0, 1), (0, 2), (1, 2))
        ]
        return cls(*d)

    def lengths(self) -> NDArray[np.float64]:
        """The distinct rigid distances of the marker set (mm, sorted)."""
        return np.unique(np.r_[self.d_ij, self.d_ik, self.d_jk])

    def __len__(self) -> int:
        return len(self.d_ij)


def body_error(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    known_xyz: NDArray[np.float64],
    known_field: NDArray[np.int64],
    triangles: RigidTriangles,
) -> NDArray[np.float64]:
    """How well each point fits a rigid triangle with two known points of its field.

    Returns, per point (``xyz`` (n, 3) in ``field`` (n,)), the smallest over the
    triangles and the ordered pairs of distinct known points q, r of its field of
    ``max(| |p - q| - d_ij |, | |p - r| - d_ik |, | |q - r| - d_jk |)`` (mm); inf where
    the field has fewer than two known points.
    """
    out = np.full(len(xyz), np.inf)
    good = np.all(np.isfinite(known_xyz), axis=1)
    order = np.argsort(known_field[good], kind="stable")
    k_field, k_xyz = known_field[good][order], known_xyz[good][order]
    if len(triangles) == 0:
        return out
    rows_ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    for f in np.unique(field[rows_ok]):  # per field: a few points against a few known
        rows = rows_ok[field[rows_ok] == f]
        lo, hi = np.searchsorted(k_field, f), np.searchsorted(k_field, f, side="right")
        known = k_xyz[lo:hi]
        if len(known) < 2:
            continue
        to_known = np.linalg.norm(xyz[rows][:, None] - known[None], axis=2)
        between = np.linalg.norm(known[:, None] - known[None], axis=2)
        between[np.diag_indices(len(known))] = np.inf  # q and r distinct
        e_q = np.abs(to_known[:, :, None] - triangles.d_ij)  # (n, k, s)
        e_r = np.abs(to_known[:, :, None] - triangles.d_ik)
        e_qr = np.abs(between[:, :, None] - triangles.d_jk)  # (k, k, s)
        err = np.maximum(np.maximum(e_q[:, :, None], e_r[:, None]), e_qr[None])
        out[rows] = err.reshape(len(rows), -1).min(axis=1)
    return out


def body_pairs(
    pairs: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]],
    won: NDArray[np.bool_],
    known: tuple[NDArray[np.float64], NDArray[np.int64]],
    triangles: RigidTriangles | None,
    params: ReconParams,
) -> NDArray[np.bool_]:
    """``won`` with the candidate pairs (``pairs``: blobs a, b, point, field) added that
    fit one of the ``triangles`` (:func:`body_error` within ``params.two_camera_body_mm``)
    with the ``known`` points (xyz, field) and the pairs taken, whose blobs no taken pair
    uses and no other fitting pair shares; in rounds, as each pair taken may be the known
    point the next one needs. Without ``triangles``, ``won`` itself."""
    a, b, xyz, field = pairs
    if triangles is None:
        return won
    known_xyz, known_field = known
    tolerance_mm = params.two_camera_body_mm
    won = won.copy()
    n = int(max(a.max(initial=-1), b.max(initial=-1))) + 1
    for _ in range(_BODY_ROUNDS):
        used = np.zeros(n, dtype=bool)
        used[a[won]] = used[b[won]] = True
        free = np.flatnonzero(~won & ~used[a] & ~used[b])
        if len(free) == 0:
            break
        err = body_error(
            xyz[free],
            field[free],
            np.concatenate([known_xyz, xyz[won]]),
            np.concatenate([known_field, field[won]]),
            triangles,
        )
        fit = free[err <= tolerance_mm]
        degree = np.bincount(np.concatenate([a[fit], b[fit]]), minlength=n)
        new = fit[(degree[a[fit]] == 1) & (degree[b[fit]] == 1)]
        if len(new) == 0:
            break
        won[new] = True
    return won


#: Rounds of :func:`body_pairs`: a foot's pair taken through the shank's known points
#: makes the known point of the next foot marker.
_BODY_ROUNDS = 4
