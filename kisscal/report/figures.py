"""Figures the report draws itself from trajectories: the stick and thrown-marker checks.

Matplotlib object API (no pyplot state), Agg canvas. Ranges are chosen so that noise
looks like noise: a length axis spans at least a few millimetres around the true value.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kisscal._shared import fixed_margins, new_figure
from kisscal.report.validation import StickLength, ThrowFit

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Least half-range of a length axis (mm): sub-millimetre noise must not fill the panel.
MIN_HALF_RANGE_MM = 3.0
#: The stick and throw figures' two panels (9 x 3 inches, a title above).
_PAIR = fixed_margins((9.0, 3.0), (1, 2), (0.7, 0.15, 0.5, 0.4), (0.8, 0))


def nice_number(value: float) -> float:
    """The 1, 2 or 5 x 10^k nearest below ``value`` (for scale keys).

    Examples
    --------
    >>> nice_number(0.0173), nice_number(3.2), nice_number(0.8)
    (0.01, 2.0, 0.5)
    """
    if not np.isfinite(value) or value <= 0:
        return 1.0
    exponent = np.floor(np.log10(value))
    mantissa = value / 10**exponent
    step = 5.0 if mantissa >= 5 else 2.0 if mantissa >= 2 else 1.0
    return float(step * 10**exponent)


def arrow_gain(vectors: np.ndarray, length_px: float) -> float:
    """Magnification that draws the 95th-percentile vector ``length_px`` long.

    A percentile rather than the largest: one outlier must not shrink every other arrow
    to nothing (the "empty residual panel").
    """
    v = np.asarray(vectors, dtype=float).reshape(-1, 2)
    norm = np.hypot(v[:, 0], v[:, 1])
    norm = norm[np.isfinite(norm)]
    typical = float(np.percentile(norm, 95)) if len(norm) else 0.0
    return length_px / typical if typical > 0 else 1.0


def scale_key(ax, arrows, length: float, label: str, fontsize: float = 7) -> None:
    """The key arrow of a quiver, in a band added at the bottom of the panel.

    Above the panel it would sit on the title's line and cover it; inside the band it
    covers neither the title nor the data. Call after the panel's limits are final (and
    the y axis inverted, for images).
    """
    bottom, top = ax.get_ylim()
    band = 0.14 * abs(top - bottom)
    ax.set_ylim(bottom + band if bottom > top else bottom - band, top)
    font = {"size": fontsize}
    ax.quiverkey(
        arrows, 0.80, 0.05, length, label, labelpos="E", coordinates="axes", fontproperties=font
    )


def image_outline(ax, size_px: tuple[int, int], *style: str, **kw: object) -> None:
    """Draw the edge of an image of ``size_px`` (width, height) on ``ax``: pixel centres
    are at whole numbers, so the edge runs half a pixel outside the outer ones."""
    w, h = size_px[0] - 0.5, size_px[1] - 0.5
    ax.plot([-0.5, w, w, -0.5, -0.5], [-0.5, -0.5, h, h, -0.5], *style, **kw)


def panel_grid(
    rows: int,
    cols: int,
    panel_in: tuple[float, float],
    margins_in: tuple[float, float, float, float] = (0.6, 0.15, 0.45, 0.1),
    gaps_in: tuple[float, float] = (0.45, 0.3),
    sharex: bool = True,
) -> tuple[Figure, np.ndarray]:
    """A figure of ``rows`` x ``cols`` panels of ``panel_in`` (width, height) inches, laid
    out once here: ``margins_in`` (left, right, bottom, top) and ``gaps_in`` (between
    columns, between rows) hold the tick labels, axis labels and small panel titles.

    Fixed margins instead of matplotlib's constrained layout: its placement draws every
    panel twice on saving, the larger share of a many-panel figure's time. Returns the
    figure and its axes, row by row (x axes shared with ``sharex``).
    """
    left, right, bottom, top = margins_in
    gap_x, gap_y = gaps_in
    width = left + right + cols * panel_in[0] + (cols - 1) * gap_x
    height = bottom + top + rows * panel_in[1] + (rows - 1) * gap_y
    fig = new_figure(width, height, constrained=False)
    layout = fixed_margins((width, height), (rows, cols), margins_in, gaps_in)
    axes = fig.subplots(rows, cols, sharex=sharex, squeeze=False, gridspec_kw=layout)
    return fig, axes.ravel()


def padded_range(values: np.ndarray, centre: float, half: float = MIN_HALF_RANGE_MM) -> tuple:
    """Axis limits around ``centre`` spanning the data and at least ``half`` each side."""
    v = values[np.isfinite(values)]
    lo = min(centre - half, float(v.min()) if len(v) else centre)
    hi = max(centre + half, float(v.max()) if len(v) else centre)
    pad = 0.05 * (hi - lo)
    return lo - pad, hi + pad


def stick_figure(stick: StickLength, title: str = "") -> Figure:
    """Stick length over time against its true length, and the error histogram.

    References
    ----------
    Shafiq, Tümer, Güler 2001, section 5.1 (the 502.5 mm stick).
    """
    fig = new_figure(9.0, 3.0, constrained=False)
    ax, hx = fig.subplots(1, 2, width_ratios=[3, 1], gridspec_kw=_PAIR)
    t, length = stick.time_s, stick.length_mm
    m, sd = stick.mean_mm, stick.sd_mm
    ax.axhspan(m - sd, m + sd, color="tab:blue", alpha=0.15, lw=0, label="mean ± SD")
    ax.plot(t, length, "-", color="tab:blue", lw=1.0, label=f"measured {stick.a}–{stick.b}")
    ax.axhline(stick.true_mm, color="k", ls="--", lw=1, label=f"true {stick.true_mm:g} mm")
    ax.set_ylim(*padded_range(length, stick.true_mm))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("stick length (mm)")
    ax.legend(fontsize=7, loc="upper right", ncol=3)
    ax.grid(alpha=0.3)
    err = stick.valid - stick.true_mm
    half = max(MIN_HALF_RANGE_MM, float(np.abs(err).max(initial=0)))
    hx.hist(err, bins=np.linspace(-half, half, 31), color="tab:blue")
    hx.axvline(0, color="k", ls="--", lw=1)
    hx.set_xlabel("length error (mm)")
    hx.set_ylabel("fields")
    fig.suptitle(
        (f"{title}: " if title else "")
        + f"stick length {m:.2f} ± {sd:.2f} mm, mean |error| {stick.mean_abs_error_mm:.2f} mm",
        fontsize=10,
    )
    return fig


def throw_figure(fit: ThrowFit, g_m_s2: float = 9.81, title: str = "") -> Figure:
    """Height of the thrown marker with its fitted parabola, and the fit residuals.

    References
    ----------
    Shafiq, Tümer, Güler 2001, section 5.1 (the thrown marker).
    """
    fig = new_figure(9.0, 3.0, constrained=False)
    ax, rx = fig.subplots(1, 2, gridspec_kw=_PAIR)
    t = fit.time_s
    dense_t = np.linspace(t.min(), t.max(), 200)
    ax.plot(t, fit.xyz_mm[:, 2], "o", ms=3, color="tab:blue", label=f"measured {fit.label}")
    parabola = np.polyval(fit.coefficients[2], dense_t)
    ax.plot(dense_t, parabola, "-", color="k", lw=1, label=f"parabola, g = {fit.g_m_s2:.3f} m/s²")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("height Z (mm)")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    residual = fit.xyz_mm - fit.fitted_mm()
    for d, colour in zip(range(3), ("tab:red", "tab:green", "tab:blue"), strict=True):
        rx.plot(t, residual[:, d], ".-", ms=3, lw=0.7, color=colour, label="XYZ"[d])
    rx.set_ylim(*padded_range(residual.ravel(), 0.0))
    rx.set_xlabel("time (s)")
    rx.set_ylabel("residual to the fit (mm)")
    rx.legend(fontsize=7, ncol=3)
    rx.grid(alpha=0.3)
    ax_, ay_, _ = fit.acceleration_m_s2
    rel = 100 * (fit.g_m_s2 - g_m_s2) / g_m_s2
    fig.suptitle(
        (f"{title}: " if title else "")
        + f"g = {fit.g_m_s2:.3f} m/s² ({rel:+.2f} % of {g_m_s2:g}); horizontal "
        f"{ax_:+.3f}, {ay_:+.3f} m/s²; fit rms {fit.rms_mm:.2f} mm",
        fontsize=10,
    )
    return fig
