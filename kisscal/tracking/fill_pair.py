"""Two markers of a segment placed together from the one blob their images merge into.

Where the only camera that sees a marker gives one blob for it and a segment partner
(heel and ankle in line with the camera's sight, lowcost seed 361's RANK and RHEE, 2 px
apart) and neither is known there, no single-camera fill takes the blob: its ray misses
both markers, and :mod:`.fill_unmerged` needs the partner placed to take its share out.
The blob still tells where the pair lies: its centroid is the mean of the two images
weighted by their areas, which fall with the square of the depth (:mod:`kisscal.recon.
deblend`). Per field, the six coordinates of the two markers are fitted by least squares
(Moré 1978, :func:`scipy.optimize.least_squares`) to:

* each merged blob's centroid (SD :data:`CENTROID_SD_PX`);
* the pair's length and each one's length to the partners measured there (the trial's
  lengths and SDs, :func:`~kisscal.tracking.segment_lengths.length_partners`);
* each marker's path across the gap from its samples on each side (a random walk on its
  acceleration, :func:`~kisscal.tracking.fill_sphere.smooth_depth`, per axis).

The expected error is the marker's part of the fit's covariance ``(JᵀJ)⁻¹`` (RMS over
the three axes); a field is placed when it is at most ``ray_depth_max_error_mm``, every
datum is within three SDs and the two images at the fit lie within ``ray_merge_px`` of
each other (farther, the camera would have seen two blobs), in runs of at least
:data:`~kisscal.tracking.on_rays.MIN_RUN` fields. :class:`PairFit` says why a gap was
refused.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera); Challis 1995 (segments as rigid
bodies of markers); Moré 1978 (Levenberg-Marquardt); Rauch, Tung & Striebel 1965
(smoothing a random walk).
"""

from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from kisscal.dlt.model import project_rows
from kisscal.tracking.fill_sphere import smooth_depth
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.segment_lengths import length_partners, partner_lengths

#: SD (px) of a merged blob's centroid about the area-weighted mean of its two images: a
#: detector's centroid of two touching images is off that mean by a fraction of a pixel.
CENTROID_SD_PX = 0.3

#: SDs within which every datum of a field's fit must lie for the field to be placed.
FIT_SDS = 3.0


@dataclass(frozen=True)
class PairFit:
    """The fit of a gap: the marker's placed fields (``fill``, None when none) and, when
    none was placed, why (``reason``)."""

    fill: ChainFill | None
    reason: str = ""


def path_prior(
    series: NDArray, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray, NDArray]:
    """Mean (hi - lo, 3) and SD (hi - lo,) of a marker's path over [lo, hi) from its samples
    within ``fill_context_fields`` each side (SD ``ray_length_sd_floor_mm``), a random walk
    on its second difference whose SD is the larger of its RMS there and over the trial;
    NaN without two samples."""
    w = params.fill_context_fields
    a = max(lo - w, 0)
    ok = np.all(np.isfinite(series), axis=1)
    ok[lo:hi] = False
    idx = np.flatnonzero(ok[a : hi + w])
    n = min(hi + w, len(series)) - a
    if idx.size < 2:
        return np.full((hi - lo, 3), np.nan), np.full(hi - lo, np.nan)
    dd = np.diff(series, 2, axis=0)
    near = dd[max(a - 1, 0) : hi + w]
    rms = [np.sqrt(np.nanmean(np.sum(d**2, axis=1))) for d in (near, dd) if np.isfinite(d).any()]
    acc = max(max(rms, default=0.0), 0.1)
    sd = np.full(idx.size, params.ray_length_sd_floor_mm)
    fits = [smooth_depth(n, idx, series[a + idx, k], sd, acc) for k in range(3)]
    mean = np.stack([m for m, _ in fits], axis=1)[lo - a : hi - a]
    return mean, fits[0][1][lo - a : hi - a]


def _blobs(
    spare: SpareBlobs, f: int, guess: NDArray, gate_px: float, gate_mm: float
) -> NDArray[np.int64]:
    """Free blob rows of field ``f``, one per camera, nearest the weighted mean of the
    pair's images at ``guess`` (2, 3) within ``gate_px`` plus ``gate_mm`` seen there,
    where no second blob is."""
    rows = spare.rows(f, f + 1)
    out = []
    for cam in np.unique(spare.camera[rows]):
        mine = rows[spare.camera[rows] == cam]
        uv = project_rows(
            spare.dlts, np.full(4, cam), guess[0] + np.r_[np.zeros((1, 3)), np.eye(3)]
        )
        gate = gate_px + gate_mm * np.linalg.norm(uv[1:] - uv[0], axis=1).max()
        d = np.linalg.norm(spare.uv_px[mine] - _centroid(spare.dlts[cam], guess), axis=1)
        if np.sum(d <= gate) == 1:
            out.append(int(mine[np.argmin(d)]))
    return np.asarray(out, dtype=np.int64)


def _centroid(dlt: NDArray, xyz: NDArray, kind: int = 2) -> NDArray[np.float64]:
    """The image of ``xyz[kind]`` (2, 3) in camera ``dlt``, or with ``kind`` 2 the
    area-weighted mean of both images: the DLT's denominator is proportional to depth, an
    image's area to its inverse square."""
    uv = project_rows(dlt[None], np.zeros(2, dtype=np.int64), xyz)
    w = 1.0 / (xyz @ dlt[8:11] + 1.0) ** 2
    w = w if kind == 2 else np.eye(2)[kind]
    return (w @ uv) / w.sum()


def _field_fit(
    spare: SpareBlobs, rows: NDArray, kinds: tuple, prior: tuple[NDArray, NDArray], lengths: list
) -> tuple[NDArray, NDArray, float, float, float]:
    """One field: the pair (2, 3), its covariance (6, 6), the largest datum's residual in
    SDs, the largest distance (px) between the pair's images in a merged blob's camera
    and the fit's cost. ``kinds``: per blob, 2 when merged, else which marker it is;
    ``prior``: means (2, 3) and SDs (2,); ``lengths``: (i, point or None for the pair's
    other marker, length, SD) with ``i`` 0 or 1."""
    mean, sd = prior
    cams = spare.camera[rows]

    def data(x: NDArray) -> NDArray:
        xyz = x.reshape(2, 3)
        blob = [
            (_centroid(spare.dlts[c], xyz, kind) - spare.uv_px[r]) / CENTROID_SD_PX
            for c, r, kind in zip(cams, rows, kinds, strict=True)
        ]
        lens = [
            (np.linalg.norm(xyz[i] - (xyz[1 - i] if q is None else q)) - L) / s
            for i, q, L, s in lengths
        ]
        return np.r_[np.ravel(blob), lens]

    def fun(x: NDArray) -> NDArray:
        return np.r_[data(x), ((x.reshape(2, 3) - mean) / sd[:, None]).ravel()]

    got = least_squares(fun, mean.ravel(), method="lm")
    cov = np.linalg.pinv(got.jac.T @ got.jac)
    xyz = got.x.reshape(2, 3)
    apart = max(
        float(np.linalg.norm(np.diff(project_rows(spare.dlts, np.r_[c, c], xyz), axis=0)))
        for c, kind in zip(cams, kinds, strict=True)
        if kind == 2
    )
    return xyz, cov, float(np.abs(data(got.x)).max()), apart, float(got.cost)


def _best_reading(
    spare: SpareBlobs,
    rows: NDArray,
    prior: tuple,
    lengths: list,
    params: TrackingParams,
    why: Counter,
) -> tuple[NDArray, float] | None:
    """The marker's point and expected error from the blobs ``rows`` of a field, each read
    as merged (one at least) or as one marker's alone, the reading of least cost that
    holds (:func:`_field_fit`); None when none holds, or two place it apart (reasons
    into ``why``)."""
    fits = []
    for kinds in itertools.product((2, 0, 1), repeat=rows.size):
        if 2 not in kinds:
            continue
        got, cov, worst, apart, cost = _field_fit(spare, rows, kinds, prior, lengths)
        err = float(np.sqrt(np.trace(cov[:3, :3]) / 3.0))
        if worst > FIT_SDS or apart > params.ray_merge_px:
            why["the merged-pair model does not hold"] += 1
        elif err > params.ray_depth_max_error_mm:
            why["not determined"] += 1
        else:
            fits.append((cost, got[0], err))
    fits.sort(key=lambda x: x[0])
    # two readings of the blobs that place the marker apart: the blobs do not tell
    if len(fits) > 1 and np.linalg.norm(fits[1][1] - fits[0][1]) > 2.0 * fits[0][2]:
        why["blobs read two ways"] += 1
        return None
    return (fits[0][1], fits[0][2]) if fits else None


def pair_fit(
    dense: NDArray,
    t: int,
    p: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    known: NDArray,
    mirror: NDArray | None = None,
) -> PairFit:
    """Track ``t``'s fields of [lo, hi) placed with its partner ``p`` (neither measured
    there) from the blobs their images merge into (see module)."""
    prior = [path_prior(dense[u], lo, hi, params) for u in (t, p)]
    if not all(np.isfinite(s).all() for _, s in prior):
        return PairFit(None, "no path across the gap for both markers")
    pairs = []
    for u in (t, p):
        part, psd = length_partners(dense, u, params, mirror)
        lens = partner_lengths(dense, u, part, lo, hi, params.body_context_fields)
        pairs.append((part, psd, lens))
    at = np.flatnonzero(pairs[0][0] == p)
    if at.size == 0:
        return PairFit(None, "the two markers keep no length in the trial")
    xyz, sd = np.full((hi - lo, 3), np.nan), np.full(hi - lo, np.nan)
    why: Counter[str] = Counter()
    for k in range(hi - lo):
        f = lo + k
        mean = np.stack([prior[0][0][k], prior[1][0][k]])
        psd = np.array([prior[0][1][k], prior[1][1][k]])
        rows = _blobs(spare, f, mean, params.ray_chain_gate_px, FIT_SDS * psd.max())
        if rows.size == 0:
            why["no single merged blob"] += 1
            continue
        lengths = [(0, None, pairs[0][2][k, at[0]], pairs[0][1][at[0]])]
        for i, (part, psd_i, lens) in enumerate(pairs):
            for j, q in enumerate(part):
                if q not in (t, p) and known[q, f]:
                    lengths.append((i, dense[q, f], lens[k, j], psd_i[j]))
        got = _best_reading(spare, rows, (mean, psd), lengths, params, why)
        if got is not None:
            xyz[k], sd[k] = got
    placed = path_runs(np.isfinite(sd))
    if not placed.any():
        reasons = [f"{r} ({n} fields or readings)" for r, n in sorted(why.items())]
        return PairFit(None, "; ".join(reasons) or "no run of placed fields")
    xyz[~placed], sd[~placed] = np.nan, np.nan
    return PairFit(ChainFill(xyz, sd, (p,), np.zeros(0, dtype=np.int64)))


def merged_pair_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs | None,
    params: TrackingParams,
    known: NDArray | None = None,
    mirror: NDArray | None = None,
) -> ChainFill | None:
    """The fields of the gap [lo, hi) of track ``t`` placed by :func:`pair_fit` with the
    segment partner, measured in none of them, that places most; its blobs stay free (the
    partner's own gap takes them). None without ``spare`` or ``known`` (every track's
    measured fields) or when no partner places a field."""
    if spare is None or known is None or lo < 1 or hi >= dense.shape[1]:
        return None
    part, _ = length_partners(dense, t, params, mirror)
    best = None
    for p in part[
        (part < len(known)) & ~known[np.minimum(part, len(known) - 1), lo:hi].any(axis=1)
    ]:
        got = pair_fit(dense, t, int(p), lo, hi, spare, params, known, mirror).fill
        if got is not None and (
            best is None or np.isfinite(got.sd_mm).sum() > np.isfinite(best.sd_mm).sum()
        ):
            best = got
    return best
