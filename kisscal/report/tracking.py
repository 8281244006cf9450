"""Figures of the tracking stage: trajectories in three views and segment lengths.

Both return matplotlib Figures built with the object API (no pyplot state), so they work
with the Agg backend in reports and CI.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from kisscal.tracking.pipeline import Trajectories
from kisscal.tracking.tracks import FILLED, MEASURED, Tracks

_VIEWS = (("top (X-Y)", 0, 1), ("side (X-Z)", 0, 2), ("front (Y-Z)", 1, 2))


def trajectory_views(tracks: Tracks, labels: tuple[str, ...], title: str = "") -> Figure:
    """Three orthogonal views of every trajectory (like the thesis' top, right and front
    views); gaps stay gaps, filled samples are drawn as small crosses."""
    fig = Figure(figsize=(15, 5), layout="constrained")
    axes = fig.subplots(1, 3)
    dense = tracks.positions() if tracks.field.size else np.zeros((0, 0, 3))
    colours = [f"C{i % 10}" for i in range(tracks.n_tracks)]
    for ax, (name, i, j) in zip(axes, _VIEWS, strict=True):
        for t in range(tracks.n_tracks):
            ax.plot(dense[t, :, i], dense[t, :, j], color=colours[t], lw=0.8, label=labels[t])
            filled = (tracks.track == t) & (tracks.status == FILLED)
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


def trajectories_figure(result: Trajectories, title: str = "") -> Figure:
    """:func:`trajectory_views` of a :class:`~kisscal.tracking.Trajectories` result."""
    return trajectory_views(result.tracks, result.labels, title)


def segment_length_figure(
    result: Trajectories,
    segments: list[tuple[str, str]] | tuple,
    rate_hz: float | None = None,
    title: str = "",
) -> Figure:
    """Length of each segment over time, from measured points (solid) and from the Kalman
    a-posteriori estimates (dashed), as in Küçük 2005 chapter 5. Time in seconds when
    ``rate_hz`` is given, else in fields."""
    tracks, labels = result.tracks, result.labels
    index = {name: k for k, name in enumerate(labels)}
    pairs = [p for p in segments if p[0] in index and p[1] in index]
    fig = Figure(figsize=(10, 1.8 + 1.6 * max(len(pairs), 1)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(max(len(pairs), 1), 1, sharex=True))
    if not pairs or tracks.field.size == 0:
        axes[0].text(0.5, 0.5, "no labelled segment", ha="center", va="center")
        return fig
    n_fields = int(tracks.field.max()) + 1
    measured = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    m = tracks.status == MEASURED
    measured[tracks.track[m], tracks.field[m]] = tracks.xyz_mm[m]
    corrected = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    corrected[tracks.track, tracks.field] = tracks.corrected_mm
    time_axis = np.arange(n_fields) / (rate_hz or 1.0)
    for ax, (a, b) in zip(axes, pairs, strict=False):
        for dense, style, name in ((measured, "-", "measured"), (corrected, "--", "corrected")):
            length = np.linalg.norm(dense[index[a]] - dense[index[b]], axis=1)
            ax.plot(time_axis, length, style, lw=0.8, label=name)
        ax.set_ylabel(f"{a}-{b}\n(mm)")
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("time (s)" if rate_hz else "field")
    if title:
        fig.suptitle(title)
    return fig
