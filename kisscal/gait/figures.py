"""The gait-cycle figure: heel and toe height and forward speed per side, events marked.

Built with matplotlib's object API (no pyplot state), for reports and CI (Agg backend).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from kisscal._shared import fixed_margins, new_figure
from kisscal.gait.events import progression
from kisscal.gait.markers import GaitMarkers
from kisscal.gait.params import DEFAULT_PARAMS, GaitParams
from kisscal.gait.signals import derivative
from kisscal.gait.table import SIDES, GaitEvents

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_STYLE = {"foot_strike": ("-", "FS"), "foot_off": ("--", "FO")}


def gait_cycle_figure(
    markers: GaitMarkers,
    events: GaitEvents,
    truth: GaitEvents | None = None,
    title: str = "",
    params: GaitParams = DEFAULT_PARAMS,
) -> Figure:
    """Heel and toe height (top) and forward speed (bottom) against time, per side.

    Foot strikes are solid vertical lines, foot offs dashed (blue: detected); with
    ``truth`` (synthetic trials), the true events are drawn too (thin grey). Forward
    speed is along the local direction of progression (:func:`kisscal.gait.progression`),
    with the pelvis' for reference.

    Parameters
    ----------
    markers : GaitMarkers
    events : GaitEvents
    truth : GaitEvents, optional
    title : str
    params : GaitParams
        For the derivative window and the direction of progression.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(200) / 100.0
    >>> walk = np.column_stack([1000.0 * t, np.zeros(200), 50 + 0 * t])
    >>> gm = GaitMarkers((walk,), {"left": walk, "right": walk}, {"left": walk, "right": walk},
    ...                  100.0, {})
    >>> fig = gait_cycle_figure(gm, GaitEvents.from_times({}, 100.0))
    >>> len(fig.axes)
    4
    """
    t = markers.time_s
    direction, pelvis_v = progression(markers, params)
    margins = (0.75, 0.15, 0.5, 0.3 + (0.35 if title else 0.0))
    fig = new_figure(12, 6.5, constrained=False)
    axes = fig.subplots(
        2, 2, sharex=True, gridspec_kw=fixed_margins((12, 6.5), (2, 2), margins, (0.8, 0.35))
    )
    pelvis_fwd = np.sum(pelvis_v[:, :2] * direction, axis=1) / 1000.0
    for col, side in enumerate(SIDES):
        top, bottom = axes[0, col], axes[1, col]
        for role, colour in (("heel", "C3"), ("toe", "C2")):
            track = getattr(markers, role)[side]
            name = markers.names.get(f"{side}_{role}", role)
            top.plot(t, track[:, 2], color=colour, lw=1.0, label=f"{name} height")
            v = derivative(track, markers.rate_hz, params.derivative_ms)
            fwd = np.sum(v[:, :2] * direction, axis=1) / 1000.0
            bottom.plot(t, fwd, color=colour, lw=1.0, label=f"{name} forward")
        bottom.plot(t, pelvis_fwd, color="0.5", lw=0.8, label="pelvis forward")
        for ax in (top, bottom):
            _mark(ax, events, side, "C0", 1.2)
            if truth is not None:
                _mark(ax, truth, side, "0.4", 0.6)
        counts = [f"{len(events.times(side, e))} {label}" for e, (_, label) in _STYLE.items()]
        top.set_title(f"{side} ({', '.join(counts)}; solid FS, dashed FO)")
        top.set_ylabel("height (mm)")
        bottom.set_ylabel("forward speed (m/s)")
        bottom.set_xlabel("time (s)")
        top.legend(fontsize=7, loc="upper right")
        bottom.legend(fontsize=7, loc="upper right")
    if title:
        fig.suptitle(title)
    return fig


def _mark(ax, events: GaitEvents, side: str, colour: str, width: float) -> None:
    for event, (style, _) in _STYLE.items():
        for x in events.times(side, event):
            ax.axvline(x, color=colour, ls=style, lw=width)
