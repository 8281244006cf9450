"""Figures of the tracking stage: trajectories in three views and segment lengths.

Both return matplotlib Figures built with the object API (no pyplot state), so they work
with the Agg backend in reports and CI.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kisscal.errors import InputError
from kisscal.report.figures import padded_range, panel_grid
from kisscal.tracking.pipeline import Trajectories
from kisscal.tracking.tracks import MEASURED, is_filled

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_VIEWS = (("top (X-Y)", 0, 1), ("side (X-Z)", 0, 2), ("front (Y-Z)", 1, 2))


def trajectories_figure(result: Trajectories, title: str = "") -> Figure:
    """Three orthogonal views of every trajectory (like the thesis' top, right and front
    views); gaps stay gaps, filled samples are drawn as small crosses."""
    tracks, labels = result.tracks, result.labels
    top = 0.3 + (0.35 if title else 0.0)  # the panels' titles, and the figure's
    fig, axes = panel_grid(1, 3, (4.1, 4.0), (0.95, 0.15, 0.55, top), (0.95, 0.0), sharex=False)
    dense = tracks.positions() if tracks.field.size else np.zeros((0, 0, 3))
    colours = [f"C{i % 10}" for i in range(tracks.n_tracks)]
    for ax, (name, i, j) in zip(axes, _VIEWS, strict=True):
        for t in range(tracks.n_tracks):
            ax.plot(dense[t, :, i], dense[t, :, j], color=colours[t], lw=0.8, label=labels[t])
            filled = (tracks.track == t) & is_filled(tracks.status)
            if filled.any():
                ax.plot(
                    tracks.xyz_mm[filled, i], tracks.xyz_mm[filled, j], "x", color=colours[t], ms=3
                )
        ax.set_title(name)
        ax.set_xlabel("XYZ"[i] + " (mm)")
        ax.set_ylabel("XYZ"[j] + " (mm)")
        ax.set_aspect("equal", adjustable="datalim")
    if tracks.n_tracks:
        axes[2].legend(fontsize=6, ncol=2, loc="best")
    if title:
        fig.suptitle(title)
    return fig


def segment_length_figure(
    result: Trajectories, segments: list[tuple[str, str]] | tuple, rate_hz: float | None = None
) -> Figure:
    """Length of each segment over time, from measured points (solid) and from the Kalman
    a-posteriori estimates (dashed), as in Küçük 2005 chapter 5. Time in seconds when
    ``rate_hz`` is given, else in fields.

    One small panel per segment, three a row, titled with its mean and SD; each length axis spans at
    least :data:`~kisscal.report.figures.MIN_HALF_RANGE_MM` either side of the mean, so
    that sub-millimetre noise looks like what it is.

    Raises
    ------
    KisscalError
        When no segment has both ends among the trajectories (nothing to draw; a session
        stage then skips the figure).
    """
    tracks, labels = result.tracks, result.labels
    index = {name: k for k, name in enumerate(labels)}
    pairs = [p for p in segments if p[0] in index and p[1] in index]
    if not pairs or tracks.field.size == 0:
        raise InputError("segment length figure: no labelled segment to draw")
    n_fields = int(tracks.field.max()) + 1
    measured = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    m = tracks.status == MEASURED
    measured[tracks.track[m], tracks.field[m]] = tracks.xyz_mm[m]
    corrected = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    corrected[tracks.track, tracks.field] = tracks.corrected_mm
    time_axis = np.arange(n_fields) / (rate_hz or 1.0)
    cols = min(3, len(pairs))
    rows = -(-len(pairs) // cols)
    fig, axes = panel_grid(rows, cols, (3.4, 1.35), margins_in=(0.6, 0.15, 0.45, 0.3))
    for ax in axes[len(pairs) :]:
        fig.delaxes(ax)
    for ax, (a, b) in zip(axes, pairs, strict=False):
        lengths = []
        for dense, style, name in ((measured, "-", "measured"), (corrected, "--", "corrected")):
            length = np.linalg.norm(dense[index[a]] - dense[index[b]], axis=1)
            ax.plot(time_axis, length, style, lw=0.8, label=name)
            lengths.append(length)
        ok = lengths[0][np.isfinite(lengths[0])]
        mean = float(ok.mean()) if len(ok) else float(np.nanmean(lengths[1]))
        sd = float(ok.std()) if len(ok) else float("nan")
        ax.set_ylim(*padded_range(np.concatenate(lengths), mean))
        ax.set_title(f"{a}-{b}: {mean:.1f} mm, SD {sd:.2f} mm", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("length (mm)", fontsize=8)
    axes[0].legend(fontsize=6, loc="lower right")
    for ax in axes[max(len(pairs) - cols, 0) : len(pairs)]:  # the lowest panel of each column
        ax.set_xlabel("time (s)" if rate_hz else "field", fontsize=8)
        ax.xaxis.set_tick_params(labelbottom=True)
    return fig
