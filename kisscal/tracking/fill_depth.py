"""Single-camera fill by depth: a marker on its blob's ray, its distance from the camera
bridged by a spline.

Where one camera alone sees a marker and neither the segment's lengths
(:mod:`kisscal.tracking.raychain`, :mod:`kisscal.tracking.fill_joint`) nor a body fill
place it (a shank marker whose partners are hidden too), two of its three coordinates are
still measured: it lies on the ray of its own blob, followed in the image from both sides
of the gap (:func:`~kisscal.tracking.blob_paths.chain_blobs`). The third, its distance from
that camera, changes smoothly and is bridged by a cubic interpolating spline through the
distances of the marker's measured samples on each side (``fill_context_fields``).

The fill is kept only when the same spline, run on stretches of the marker's own measured
samples of the gap's length (:func:`~kisscal.tracking.stretches.pseudo_gaps`), misses their
distance from the camera by at most ``ray_depth_max_error_mm`` RMS (or the noise of the
samples it goes through carries more into the gap, :func:`context_noise`): a marker
turning towards the camera in the gap is left to the other fills. Where the spline is
refused, a quadratic plus the stride's harmonics fitted to the samples over about three
strides (:func:`_depth_periodic`) is tried the same way, expecting at least what its
samples' noise carries and never without a stretch to try it on. A field is left out where a
second camera's blob of the marker lies farther than ``ray_depth_max_error_mm`` from the
point (:func:`~kisscal.tracking.blob_paths.off_rays`, as the sphere fill does): one of the
two blobs is not the marker's alone (lowcost seed 306's heel, its image merged with the
ankle's in the camera taken, 7-13 mm off expecting 2.5, its own blob in another).

References
----------
Hartley & Zisserman 2004 (rays of a projective camera); Gløersen & Federolf 2016 (gap
filling from what the trial measured); Winter 2009 (the trunk's speed cycling with the
stride in walking).
"""

from __future__ import annotations

from functools import partial

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline

from kisscal.dlt.model import ray_directions
from kisscal.tracking.blob_paths import chain_blobs, off_rays, one_camera_blobs
from kisscal.tracking.bodyfill import side_windows
from kisscal.tracking.fill_donors import shared_blobs
from kisscal.tracking.fill_spline import context_noise
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.segment_lengths import length_partners
from kisscal.tracking.stretches import pseudo_gaps

#: Fields on each side of a gap the periodic depth fit (:func:`_depth_periodic`) reads
#: (at lowcost's 30 Hz about three strides), and its harmonics of the stride.
PERIODIC_FIELDS, HARMONICS = 100, 3


def _periodic_design(x: NDArray, mid: float, period: float) -> NDArray[np.float64]:
    """Columns of a quadratic in ``x`` about ``mid`` and :data:`HARMONICS` of ``period``."""
    u = (x - mid) / PERIODIC_FIELDS
    w = 2 * np.pi * np.arange(1, HARMONICS + 1) * x[:, None] / period
    return np.column_stack([np.ones_like(u), u, u**2, np.cos(w), np.sin(w)])


def _depth_periodic(
    series: NDArray, centre: NDArray, lo: int, hi: int, n: int = PERIODIC_FIELDS
) -> tuple[NDArray[np.float64], float] | None:
    """Distance (mm) of ``series`` (n_fields, 3) from ``centre`` over fields [lo, hi) by a
    least-squares quadratic plus a stride's harmonics through the measured samples within
    ``n`` fields on each side, the period (n/5 to n/2 fields) the one of least residual,
    and the RMS over the gap of what the samples' noise carries into it (the fit is linear
    in them): walking, a marker's distance from a camera swings about its trend with the
    stride (lowcost 311's sacrum, 4 mm over a 16-field gap a spline through the noisy
    samples beside it, or a smooth fit, missed by 3-9 mm). None without enough samples."""
    ok = np.all(np.isfinite(series), axis=1)
    x = np.flatnonzero(ok[max(lo - n, 0) : hi + n]) + max(lo - n, 0)
    x = x[(x < lo) | (x >= hi)]
    cols = 3 + 2 * HARMONICS
    if np.sum(x < lo) < 2 or np.sum(x >= hi) < 2 or x.size < 3 * cols:
        return None
    y = np.linalg.norm(series[x] - centre, axis=1)
    mid = (lo + hi - 1) / 2
    fits = [
        (np.linalg.lstsq(_periodic_design(x, mid, p), y, rcond=None)[1], p)
        for p in np.arange(n // 5, n // 2 + 1)
    ]
    res, period = min((float(r[0]) if r.size else np.inf, p) for r, p in fits)
    weights = _periodic_design(np.arange(lo, hi), mid, period) @ np.linalg.pinv(
        _periodic_design(x, mid, period)
    )
    noise = np.sqrt(res / (x.size - cols)) * np.sqrt(np.mean(np.sum(weights**2, axis=1)))
    return weights @ y, float(noise)


def _depth_spline(
    series: NDArray, centre: NDArray, lo: int, hi: int, n: int
) -> NDArray[np.float64] | None:
    """Distance (mm) of ``series`` (n_fields, 3) from ``centre`` over fields [lo, hi): the
    cubic spline through up to ``n`` measured samples on each side (None without two)."""
    before, after = side_windows(series, lo, hi, n)
    if before.size < 2 or after.size < 2:
        return None
    f = np.r_[before, after]
    depth = np.linalg.norm(series[f] - centre, axis=1)
    return make_interp_spline(f, depth, k=min(3, f.size - 1))(np.arange(lo, hi))


def _stretch_error(
    series: NDArray,
    centre: NDArray,
    plo: int,
    phi: int,
    n: int,
    params: TrackingParams,
    periodic: bool,
) -> float:
    """RMS miss (mm) of the depth fill on the measured stretch [plo, phi) of ``series``, scaled
    up to a gap of ``n`` fields as the square of the lengths' ratio (as
    :func:`~kisscal.tracking.stretches.expected_errors`); NaN when it cannot be made."""
    cut = series.copy()
    cut[plo:phi] = np.nan
    if periodic:
        got = _depth_periodic(cut, centre, plo, phi)
        got = None if got is None else got[0]
    else:
        got = _depth_spline(cut, centre, plo, phi, params.fill_context_fields)
    if got is None:
        return float("nan")
    miss = got - np.linalg.norm(series[plo:phi] - centre, axis=1)
    return float(np.sqrt(np.mean(miss**2)) * (n / (phi - plo)) ** 2)


def depth_error(
    series: NDArray,
    centre: NDArray,
    lo: int,
    hi: int,
    params: TrackingParams,
    periodic: bool = False,
) -> float:
    """RMS error (mm) of :func:`_depth_spline` (or :func:`_depth_periodic`) on
    :func:`pseudo_gaps` beside [lo, hi) (:func:`_stretch_error`). When none of them lies
    within ``body_context_fields`` of the gap (the runs beside it too short), at least its
    error on the stretch nearest the gap of half its length or more, with
    ``fill_context_fields`` measured a side (what the spline reads): the gap's phase of
    the stride, which stretches far from it may not show (kiss 3 seed 302's tibia: 0.4
    and 1.6 mm 350 fields away, 2.7 on 6 fields beside it, 2.9 mm off). NaN without a
    stretch."""
    one = partial(_stretch_error, series, centre, n=hi - lo, params=params, periodic=periodic)
    spans = pseudo_gaps(series, lo, hi, params.body_context_fields // 2)
    err = np.array([one(*s) for s in spans])
    err = err[np.isfinite(err)]
    rms = float(np.sqrt(np.mean(err**2))) if err.size else np.nan
    if min(map(partial(_away, lo, hi), spans), default=np.inf) <= params.body_context_fields:
        return rms
    near = pseudo_gaps(series, lo, hi, params.fill_context_fields, every=True)
    near = [s for s in near if 2 * (s[1] - s[0]) >= hi - lo]
    nearest = min(near, key=partial(_away, lo, hi), default=None)
    return float(np.fmax(rms, np.nan if nearest is None else one(*nearest)))


def _away(lo: int, hi: int, stretch: tuple[int, int]) -> int:
    """Fields between the gap [lo, hi) and ``stretch`` (lo, hi) outside it."""
    return lo - stretch[1] if stretch[1] <= lo else stretch[0] - hi


def depth_ray_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    measured: NDArray | None = None,
) -> ChainFill | None:
    """Place fields of the gap [lo, hi) of track ``t`` of ``dense`` (n_tracks, n_fields,
    3; NaN where not measured) on the rays of its own blobs in the camera that sees most
    of the gap, at the spline's distance from that camera (see module); None when the
    spline's expected error exceeds ``ray_depth_max_error_mm`` or no run of
    :data:`~kisscal.tracking.on_rays.MIN_RUN` fields has a blob. The blobs taken are not
    marked used here. With ``measured`` ((n_fields,) bool), the spline and its error
    use only those samples of the track (not fields placed on rays by other fills),
    across the whole run of unmeasured fields around the gap."""
    series = dense[t]
    if lo < 2 or hi + 1 >= len(series) or not np.all(np.isfinite(series[[lo - 1, hi]])):
        return None
    ks, rows = chain_blobs(series, lo, hi, spare, params)
    if ks.size == 0:
        return None
    every = ks, rows
    cam, ks, rows = one_camera_blobs(ks, rows, spare)
    centre = spare.centres[cam]
    own, a, b = series, lo, hi
    if measured is not None:
        own = np.where(measured[:, None], series, np.nan)
        seen = np.flatnonzero(measured)
        a = int(seen[seen < lo][-1]) + 1 if np.any(seen < lo) else 0
        b = int(seen[seen >= hi][0]) if np.any(seen >= hi) else len(series)
    noise = context_noise(own, centre, a, b, params.fill_context_fields)
    # the stretches' error has their own samples' noise in it: the more of the two
    err = float(np.fmax(depth_error(own, centre, a, b, params), noise))
    depth = _depth_spline(own, centre, a, b, params.fill_context_fields)
    if depth is None or not err <= params.ray_depth_max_error_mm:
        # the stride's swing fitted instead, only where stretches beside show its error
        got = _depth_periodic(own, centre, a, b)
        if got is None:
            return None
        depth, noise = got
        err = max(depth_error(own, centre, a, b, params, periodic=True), noise)
        if not err <= params.ray_depth_max_error_mm:  # NaN without a stretch too
            return None
    depth = depth[lo - a : hi - a]
    d = ray_directions(spare.dlts[spare.camera[rows]], spare.uv_px[rows])
    d *= np.sign((series[lo - 1] - centre) @ d.T)[:, None]  # towards the marker
    at = centre + depth[ks, None] * d
    has = np.zeros(hi - lo, dtype=bool)
    has[ks] = True
    partners = length_partners(dense, t, params)[0]
    if partners.size:  # a merged blob's centroid lies off the marker's ray
        has[ks[shared_blobs(dense, t, lo, ks, rows, spare, params, partners)]] = False
    # a second camera's blob off the point: one of the two is not the marker's alone
    has[off_rays(at, ks, *every, spare, params.ray_depth_max_error_mm)] = False
    placed = path_runs(has)
    if not placed.any():
        return None
    take = placed[ks]
    ks, rows = ks[take], rows[take]
    xyz = np.full((hi - lo, 3), np.nan)
    xyz[ks] = at[take]
    sd = np.where(placed, err, np.nan)
    return ChainFill(xyz, sd, (), rows)
