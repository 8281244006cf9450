"""The rods' marker spacings as a projective signature: what any camera sees of a rod.

A camera maps positions along a straight rod to positions along its image line by a 1D
projectivity, so a rod is known by its spacings' cross-ratios (Shafiq et al. 2001,
section 3.3); rods whose spacings share those cannot be told apart in any image.

References
----------
Shafiq, M. S., Tümer, S. T., & Güler, H. C. (2001). Marker detection and trajectory
generation algorithms for a multicamera based gait analysis system. Mechatronics, 11(4),
409-437.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import line_offsets
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams, Rod
from kisscal.errors import InputError


def rod_positions(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """1D positions (mm from the top marker along the rod) and off-line distances (mm)."""
    d = p[-1] - p[0]
    d = d / np.linalg.norm(d)
    return line_offsets(p - p[0], d)


def fit_projectivity(
    s: NDArray[np.float64], t: NDArray[np.float64], w: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Least-squares 1D projectivities ``t = (a s + b) / (c s + 1)``, batched.

    ``s``, ``t``, ``w`` have shape (H, m); ``w`` (0/1) selects the points of each fit.
    Returns ``(a, b, c)`` per row, shape (H, 3). Inputs should be normalised to ~[0, 1].
    """
    A = np.stack([s, np.ones_like(s), -s * t], axis=-1) * w[..., None]
    b = t * w
    AtA = np.einsum("hmi,hmj->hij", A, A) + 1e-12 * np.eye(3)
    Atb = np.einsum("hmi,hm->hi", A, b)
    return np.linalg.solve(AtA, Atb[..., None])[..., 0]


def apply_projectivity(h: NDArray[np.float64], s: NDArray[np.float64]) -> NDArray[np.float64]:
    den = h[:, 2:3] * s + 1.0
    return (h[:, 0:1] * s + h[:, 1:2]) / den


def monotone_subsets(n: int, k: int) -> NDArray[np.int64]:
    return np.array(list(combinations(range(n), k)), dtype=np.int64).reshape(-1, k)


def rod_distinctness(rods: Sequence[Rod], n_markers: int, upright: bool = True) -> NDArray:
    """Projective distinctness of every pair of rods (Shafiq 2001 §3.3 "unique configuration").

    For rods ``a`` and ``b`` (``a == b`` included, then only different subsets), the
    smallest RMS residual, as a fraction of rod ``a``'s length, of a 1D projectivity that
    maps ``n_markers`` markers of ``b`` onto ``n_markers`` markers of ``a`` in the same
    order (and reversed when not ``upright``). Small values mean an image of some
    markers of ``b`` could be taken for ``a``.

    Returns
    -------
    ndarray, shape (n_rods, n_rods)
    """
    n = len(rods)
    out = np.full((n, n), np.inf)
    pos = [rod_positions(r.points_mm)[0] for r in rods]
    for ia in range(n):
        sa = pos[ia] / pos[ia][-1]
        sub_a = monotone_subsets(len(sa), n_markers)
        for ib in range(n):
            sb = pos[ib] / pos[ib][-1]
            sub_b = monotone_subsets(len(sb), n_markers)
            ii, jj = np.meshgrid(np.arange(len(sub_a)), np.arange(len(sub_b)), indexing="ij")
            ia_sub, ib_sub = sub_a[ii.ravel()], sub_b[jj.ravel()]
            targets = [sa[ia_sub]]
            sources = [sb[ib_sub]]
            if not upright:
                targets.append(sa[ia_sub][:, ::-1])
                sources.append(sb[ib_sub])
            if ia == ib:
                # A rod against itself: only different marker subsets are confusable.
                keep = ~np.all(ia_sub == ib_sub, axis=1)
                targets[0], sources[0] = targets[0][keep], sources[0][keep]
            if not len(targets[0]):
                continue
            t = np.concatenate(targets)
            s = np.concatenate(sources)
            h = fit_projectivity(s, t, np.ones_like(s))
            resid = apply_projectivity(h, s) - t
            out[ia, ib] = np.sqrt(np.mean(resid**2, axis=1)).min()
    return out


def validate_rods(rods: Sequence[Rod], params: DltParams = DEFAULT_PARAMS) -> None:
    """Refuse a rod configuration whose marker spacings are not projectively unique.

    Every rod seen whole must be told apart from every other under any perspective: the
    distinctness (:func:`rod_distinctness` with all markers) of each pair must reach
    ``params.rod_min_distinct``. Coincidences among partial views (a hidden marker) are
    caught per image by :func:`recognise_rods`, which refuses ambiguous fits.

    Raises
    ------
    KisscalError
        Naming the two rods whose spacings cannot be told apart.
    """
    n_full = min(len(r.points_mm) for r in rods)
    if len(rods) < 2:
        return
    d = rod_distinctness(rods, n_full, params.rods_upright)
    ia, ib = sorted(np.unravel_index(np.argmin(d), d.shape))
    if d[ia, ib] < params.rod_min_distinct:
        raise InputError(
            f"rods: marker spacings are not unique: rods {rods[ia].name} and {rods[ib].name} "
            f"differ by only {d[ia, ib]:.2%} of the rod length under perspective "
            f"(need {params.rod_min_distinct:.1%}); give every rod its own spacing pattern"
        )


#: Blob pairs whose line distances are computed at once (memory: this x blobs floats).
