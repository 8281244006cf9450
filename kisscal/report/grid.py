"""The figure of a grid linearisation: dots before/after with residual vectors.

Functions return matplotlib Figures (Agg canvas, no pyplot state); writing them is the
session layer's job.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kisscal._shared import fixed_margins, new_figure
from kisscal.grid.fit import GridFit
from kisscal.report.figures import arrow_gain, image_outline, nice_number, scale_key

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def grid_correction_figure(
    fit: GridFit,
    camera: str = "",
    size_px: tuple[int, int] | None = None,
) -> Figure:
    """Distorted dots, corrected dots and the residual vectors of the fit.

    Parameters
    ----------
    fit : GridFit
        Result of :func:`kisscal.grid.linearise_dots`.
    camera : str
        Camera id for the titles.
    size_px : (int, int), optional
        Image width and height, px, to draw the frame of the field of view.

    Returns
    -------
    Figure
        Top: distorted dots, corrected dots, the correction between them (a few px,
        magnified 5 times), missing and rejected positions.
        Bottom: residual vectors (corrected - optimal; hundredths of a pixel), magnified
        so that the 95th-percentile residual is 60 % of the dot spacing long; a key arrow
        states the scale.
    """
    q, dist, corr, opt = fit.linearisation.quality, fit.grid_uv, fit.corrected_uv, fit.optimal.uv
    fig = new_figure(9.0, 7.5, constrained=False)
    ax, bx = fig.subplots(
        2, 1, gridspec_kw=fixed_margins((9.0, 7.5), (2, 1), (0.75, 0.15, 0.55, 0.3), (0, 0.85))
    )
    ax.plot(dist[:, 0], dist[:, 1], ".", ms=3, color="tab:red", label="distorted dots")
    ax.plot(corr[:, 0], corr[:, 1], "+", ms=4, color="tab:blue", label="corrected dots")
    to_scale = {"angles": "xy", "scale_units": "xy", "scale": 1.0}  # arrows in data px
    moved = (corr - dist) * 5.0
    ax.quiver(*dist.T, *moved.T, **to_scale, width=0.0015, color="0.3", label="correction x 5")
    if len(fit.index.missing_uv):
        m = fit.index.missing_uv
        ax.plot(m[:, 0], m[:, 1], "o", mfc="none", color="tab:orange", label="missing dot")
    if len(fit.index.rejected):
        r = fit.dots_uv[fit.index.rejected]
        ax.plot(r[:, 0], r[:, 1], "x", color="0.4", label="rejected blob")
    title = f"grid linearisation {camera}".strip()
    if q is not None:
        title += (
            f": residual {q.residual_rms_before_px:.2f} -> {q.residual_rms_after_px:.3f} px RMS,"
            f" {q.dots_used} dots, {q.dots_missing} missing, {q.optimal_model} optimal grid"
        )
    ax.set_title(title, fontsize=9)
    res = corr - opt
    span = np.ptp(opt, axis=0) if len(opt) else np.ones(2)
    spacing = float(np.sqrt(max(span[0] * span[1], 1.0) / max(len(opt), 1)))
    gain = arrow_gain(res, 0.6 * spacing)
    arrows = bx.quiver(*opt.T, *(res * gain).T, **to_scale, width=0.0025, color="tab:blue")
    key = nice_number(0.6 * spacing / gain)
    magnified = f"residual vectors (corrected - optimal grid), magnified x {gain:.0f}"
    bx.set_title(magnified, fontsize=9, loc="left")
    for a in (ax, bx):
        if size_px is not None:
            image_outline(a, size_px, color="0.7", lw=0.8)
        a.set_aspect("equal")
        a.invert_yaxis()
        a.set_xlabel("u (px)")
        a.set_ylabel("v (px)")
    scale_key(bx, arrows, key * gain, f"{key:g} px", fontsize=8)
    ax.legend(fontsize=7, loc="upper right", framealpha=0.8)
    return fig
