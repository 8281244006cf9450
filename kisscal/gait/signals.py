"""Signal helpers for gait events: gap-aware derivatives, smoothing, crossings, kink fits.

The derivative is Savitzky & Golay's (1964) local quadratic fit, computed here as
``scipy.signal.savgol_filter`` computes it (:func:`savgol_slope`): importing
``scipy.signal`` imports ``scipy.stats`` with it, a third of a second of every session's
start-up for one filter.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lstsq
from scipy.ndimage import convolve1d, gaussian_filter1d

from kisscal._shared import true_runs


def window_samples(span_ms: float, rate_hz: float, minimum: int = 5) -> int:
    """An odd number of samples spanning about ``span_ms``, at least ``minimum``."""
    n = max(minimum, round(span_ms * rate_hz / 1000.0))
    return n if n % 2 else n + 1


def derivative(x: NDArray[np.float64], rate_hz: float, span_ms: float) -> NDArray[np.float64]:
    """Time derivative along axis 0 by local quadratic fits (Savitzky-Golay), gap by gap.

    Rows with any NaN are gaps; runs shorter than the fit window stay NaN.
    """
    x = np.asarray(x, dtype=float)
    out = np.full_like(x, np.nan)
    n = window_samples(span_ms, rate_hz)
    valid = np.all(np.isfinite(x.reshape(len(x), -1)), axis=1)
    for a, b in zip(*true_runs(valid), strict=True):
        if b - a >= n:
            out[a:b] = savgol_slope(x[a:b], n, 1.0 / rate_hz)
    return out


def savgol_slope(x: NDArray[np.float64], n: int, delta: float) -> NDArray[np.float64]:
    """First derivative along axis 0 by quadratic fits over ``n`` samples (odd, at most
    ``len(x)``) ``delta`` apart (Savitzky & Golay 1964): the convolution inside, the
    fit to the first and last ``n`` samples at the ends.

    The same operations, and so the same numbers, as ``scipy.signal.savgol_filter(x, n,
    2, deriv=1, delta=delta, axis=0)`` (its ``interp`` mode), without importing
    ``scipy.signal``.
    """
    half = n // 2
    t = np.arange(-half, n - half, dtype=np.float64)[::-1]  # scipy's "conv" order
    design = t ** np.arange(3, dtype=np.float64).reshape(-1, 1)
    target = np.zeros(3)
    target[1] = 1.0 / delta
    coeffs = lstsq(design, target, cond=np.finfo(np.float64).eps * max(design.shape))[0]
    out = convolve1d(x, coeffs, axis=0, mode="constant")
    for start, lo, hi in ((0, 0, half), (len(x) - n, len(x) - half, len(x))):
        out[lo:hi] = _edge_slope(x[start : start + n], lo - start, hi - start, delta)
    return out


def _edge_slope(window: NDArray[np.float64], lo: int, hi: int, delta: float) -> NDArray:
    """The slope of the quadratic fitted to ``window`` (along axis 0) at its samples
    ``lo`` to ``hi`` (scaled as numpy's ``polyfit``, evaluated by Horner's rule)."""
    shape = window.shape
    t = np.arange(0, len(window), dtype=window.dtype)
    powers = np.arange(3, dtype=window.dtype)[::-1]
    lhs = t[:, None] ** powers[None, :]
    scale = np.sqrt(np.sum(lhs * lhs, axis=0))
    lhs /= scale
    rcond = t.shape[0] * np.finfo(t.dtype).eps
    c = lstsq(lhs, window.reshape(len(window), -1), cond=rcond)[0]
    c = (c.T / scale).T
    dc = c[:-1].copy()
    dc *= np.arange(2, 0, -1, dtype=c.dtype).reshape(2, 1)
    at = np.arange(lo, hi, dtype=dc.dtype).reshape(-1, 1)
    slope = np.zeros_like(at)
    for j in range(dc.shape[0]):
        slope = slope * at + dc[j]
    return (slope / delta).reshape((hi - lo, *shape[1:]))


def smooth(x: NDArray[np.float64], sigma_samples: float) -> NDArray[np.float64]:
    """Gaussian smoothing along axis 0 that ignores NaN (normalised convolution)."""
    x = np.asarray(x, dtype=float)
    valid = np.isfinite(x)
    num = gaussian_filter1d(np.where(valid, x, 0.0), sigma_samples, axis=0, mode="constant")
    den = gaussian_filter1d(valid.astype(float), sigma_samples, axis=0, mode="constant")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(valid, num / den, np.nan)


def hysteresis_crossings(
    signal: NDArray[np.float64],
    high: NDArray[np.float64],
    low: NDArray[np.float64],
    hold: int = 1,
) -> NDArray[np.float64]:
    """Fractional sample indices where ``signal`` falls from above ``high`` to below ``low``.

    The crossing reported is the last zero crossing between the two (linear
    interpolation); a NaN between them voids the crossing, and so does a stay below
    ``low`` shorter than ``hold`` samples (a brief dip is not a change of phase), unless
    a gap cuts the stay (the marker lost, not risen again; a stay cut by the end of the
    signal is a stride cut by it, not counted).
    """
    state = np.where(signal > high, 1, np.where(signal < low, -1, 0))
    state[~np.isfinite(signal)] = 2
    idx = np.flatnonzero(state != 0)
    seq = state[idx]
    starts = idx[:-1][(seq[:-1] == 1) & (seq[1:] == -1)]
    ends = idx[1:][(seq[:-1] == 1) & (seq[1:] == -1)]
    out = []
    below = np.concatenate([signal < low, [False]])
    run_end = np.flatnonzero(~below)  # first sample at or after each index that is not below
    risen = np.concatenate([np.isfinite(signal), [True]])  # or in a gap
    for a, b in zip(starts, ends, strict=True):  # one per stride
        end = run_end[np.searchsorted(run_end, b)]
        if end - b < hold and risen[end]:
            continue
        seg = signal[a : b + 1]
        j = a + int(np.flatnonzero((seg[:-1] > 0) & (seg[1:] <= 0))[-1])
        out.append(j + signal[j] / (signal[j] - signal[j + 1]))
    return np.asarray(out, dtype=float)


def first_within(t: NDArray, y: NDArray, start: float, i: int, margin: float) -> int:
    """First sample from time ``start`` up to sample ``i`` where ``y`` is within
    ``margin`` of ``y[i]`` (a minimum): where a falling signal first reached its floor."""
    near = np.flatnonzero((t >= start) & (np.arange(len(y)) <= i) & (y <= y[i] + margin))
    return int(near[0])


def kink_time(
    t: NDArray[np.float64],
    y: NDArray[np.float64],
    centre: float,
    half_s: float,
    search_s: float,
    order: int = 1,
    earliest: float = -np.inf,
) -> float:
    """Time where ``y`` turns a corner near ``centre``, and not before ``earliest``:
    sub-sample.

    ``order=0``: two straight lines meet at ``t0`` (a V; for short windows).
    ``order=1``: the slope jumps; two quadratics meet at ``t0`` (``y = c0 + c1 tau +
    c2 tau^2 + c3 tau+ + c4 tau+^2``, ``tau = t - t0``, ``tau+ = max(tau, 0)``).
    ``order=2``: the curvature jumps; two cubics meet at ``t0`` with equal slopes
    (``c0 + c1 tau + c2 tau^2 + c3 tau^3 + c4 tau+^2 + c5 tau+^3``). The samples within
    ``half_s`` of ``centre`` are fitted by least squares for candidate ``t0`` every 1/20
    sample within ``search_s`` of ``centre``, and the best ``t0`` is returned (a
    broken-curve regression). NaN if the window holds too few samples or the best
    corner lies at the edge of the searched range.
    """
    sel = np.isfinite(y) & (np.abs(t - centre) <= half_s)
    tt, yy = t[sel], y[sel]
    if len(tt) < 4 + 2 * order:
        return float("nan")
    dt = float(np.median(np.diff(tt)))
    reach = max(search_s, 2.0 * dt)
    inner = 0.0 if order == 0 else dt
    lo = max(centre - reach, tt[1] + inner, earliest)
    hi = min(centre + reach, tt[-2] - inner)
    cands = np.arange(lo, hi + 1e-12, dt / 20.0)
    if len(cands) < 3:
        return float("nan")
    tau = (tt[None, :] - cands[:, None]) / half_s
    after = np.clip(tau, 0.0, None)
    if order == 0:
        cols = [np.ones_like(tau), tau, after]
    elif order == 1:
        cols = [np.ones_like(tau), tau, tau**2, after, after**2]
    else:
        cols = [np.ones_like(tau), tau, tau**2, tau**3, after**2, after**3]
    basis = np.stack(cols, axis=-1)
    gram = np.einsum("gnp,gnq->gpq", basis, basis)
    rhs = np.einsum("gnp,n->gp", basis, yy)
    coef = np.linalg.solve(gram, rhs[..., None])[..., 0]
    rss = np.sum((yy[None, :] - np.einsum("gnp,gp->gn", basis, coef)) ** 2, axis=1)
    best = int(np.argmin(rss))
    if best in (0, len(cands) - 1):
        return float("nan")
    return float(cands[best])
