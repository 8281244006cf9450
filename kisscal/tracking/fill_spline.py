"""Spline fill: a short gap bridged by a cubic spline through the samples beside it, and
the noise those samples carry into the gap.

A spline fills the gaps too short for the body to matter; its expected error is at
least what the scatter of the samples it goes through carries across the gap, which the
stretches a fill is tried on (:func:`~kisscal.tracking.stretches.expected_errors`) do not
show beside a gap few cameras see.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline

from kisscal.tracking.bodyfill import side_windows
from kisscal.tracking.fill_donors import merged_edges
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.segment_lengths import length_partners


def spline_fill(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
    """Fill fields [lo, hi) of ``target`` (n_fields, 3; NaN where not measured) by a cubic
    interpolating spline through up to ``fill_context_fields`` measured samples on each
    side (the signature of the other methods; ``dense`` and ``exclude`` are not used)."""
    ok = np.all(np.isfinite(target), axis=1)
    mf = np.flatnonzero(ok)
    i = int(np.searchsorted(mf, lo))
    ctx = max(params.fill_context_fields, 2)
    sel = slice(max(i - ctx, 0), min(i + ctx, mf.size))
    if i == 0 or i == mf.size:
        return None
    k = min(3, sel.stop - sel.start - 1)
    return make_interp_spline(mf[sel], target[mf[sel]], k=k)(np.arange(lo, hi)), ()


def context_noise(series: NDArray, centre: NDArray | None, lo: int, hi: int, n: int) -> float:
    """RMS (mm) over the gap [lo, hi) of what the noise of the up to ``n`` samples a side
    a cubic interpolating spline goes through carries into it: their scatter about a
    quadratic on each side, times the norm of each gap field's weights on them (the
    spline is linear in them; across a gap it swings by several times their noise). Of
    the positions of ``series`` (:func:`spline_fill`), or with ``centre`` (3,) of their
    distances from it (:mod:`.fill_depth`). The stretches a fill's error is measured on
    have samples of their own noise, not these (lowcost seed 311's sacrum across 16
    fields beside samples 2.4 mm off: its depth 0.68 mm expected on the stretches, this
    8.8, 8.95 mm RMS off). NaN with under four samples a side (no scatter to measure)."""
    sides = side_windows(series, lo, hi, n)
    if min(s.size for s in sides) < 4:
        return float("nan")
    f = np.concatenate(sides)
    value = series[f] if centre is None else np.linalg.norm(series[f] - centre, axis=1)
    res = [
        np.sum(np.polynomial.polynomial.polyfit(s - s[0], v, 2, full=True)[1][0])
        for s, v in zip(sides, np.split(value, [sides[0].size]), strict=True)
    ]
    sd = np.sqrt(np.sum(res) / (f.size - 6))
    weights = make_interp_spline(f, np.eye(f.size), k=3)(np.arange(lo, hi))
    return float(sd * np.sqrt(np.mean(np.sum(weights**2, axis=1))))


def sight_noise(series: NDArray, centres: NDArray, lo: int, hi: int, n: int) -> float:
    """The largest :func:`context_noise` of the distances from each camera centre of
    ``centres`` (k, 3): what a ray of one of them leaves of it. Not a third of the whole:
    a point of two cameras is off mostly along each one's sight (lowcost seed 362: splines
    through such samples 10-13 mm off along the ray that still saw the marker, expecting
    a third of their noise, 1.2-3.5 mm). NaN without centres or samples to measure."""
    return max((context_noise(series, c, lo, hi, n) for c in centres), default=float("nan"))


#: How far (in ``max_body_fill_error_mm``) a gap-edge sample on a blob another marker's
#: image may share lies from the spline through the rest before a spline leaves it out
#: (:func:`unpulled`). Two: a spline across the longer hole misses a moving foot by more
#: than one (kiss 3 seed 424: samples on their own blobs 5.6 and 8.4 mm from it, left
#: out, took its filled RMS 1.52 -> 2.50 mm); merged ones lay 21 mm from it (lowcost 437).
EDGE_PULL_ERRORS = 2.0


def _pulled(series: NDArray, edges: list[int], params: TrackingParams) -> list[int]:
    """The samples of ``series`` at ``edges`` farther than :data:`EDGE_PULL_ERRORS`
    times ``max_body_fill_error_mm`` from the spline through the rest
    (:func:`spline_fill`): a blob another marker's image may share is not always merged
    (the other's image hidden, or seen apart), and a sample on the marker's own blob is
    the spline's best context (lowcost 412: leaving every such one out lost fills,
    coverage min 100 -> 99.74 %)."""
    if not edges:
        return []
    rest = series.copy()
    rest[edges] = np.nan
    out = []
    for f in edges:
        got = spline_fill(rest, rest[None], 0, f, f + 1, params)
        if (
            got is not None
            and np.linalg.norm(got[0][0] - series[f])
            > EDGE_PULL_ERRORS * params.max_body_fill_error_mm
        ):
            out.append(f)
    return out


def unpulled(dense: NDArray, gap: Gap, lo: int, hi: int, params: TrackingParams) -> NDArray:
    """``dense`` with the samples of ``gap``'s track at the edges of [lo, hi) left out
    where one of their blobs another track's image may share
    (:func:`~kisscal.tracking.fill_donors.merged_edges`) and they lie off the spline
    through the rest (:func:`_pulled`): for a spline with blobs in its gap. A spline
    through such a sample carries its pull into the gap (lowcost 4 seed 437: an ankle's
    sample 23 mm off, its blob in camera 1 merged with the toe's, the spline 24 mm RMS
    off expecting 6.1)."""
    t, seen = gap.t, gap.dense  # the blobs are of every track's samples, not the donors'
    partners = length_partners(seen, t, params, gap.mirror)[0]
    edges = merged_edges(seen, t, lo, hi, gap.spare, params, partners)
    edges = _pulled(seen[t], edges, params)
    if not edges:
        return dense
    out = dense.copy()
    out[t, edges] = np.nan
    return out
