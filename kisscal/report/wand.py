"""Figures of a wand calibration: where the wand was in each camera's image, and its length.

The coverage figure is what a technician checks before trusting the lens terms: a
camera whose image the wand never reached near the edges has its distortion there
extrapolated. The length figure shows the wand length measured field by field over the
trial against the stated length.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from kisscal._shared import new_figure
from kisscal.report.figures import image_outline

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class WandView:
    """One camera's wand images: positions (px), image size, covered fraction, residual."""

    uv_px: ArrayLike
    size_px: tuple[int, int]
    coverage: float
    rms_px: float


def coverage_figure(cameras: Mapping[str, WandView], columns: int = 3) -> Figure:
    """Every camera's wand marker images over its image frame (one panel each).

    Example
    -------
    >>> import numpy as np
    >>> view = WandView(np.random.default_rng(0).uniform(0, 100, (50, 2)), (120, 100), 0.6, 0.1)
    >>> fig = coverage_figure({"cam1": view, "cam2": view})
    >>> len(fig.axes)
    2
    """
    names = list(cameras)
    n = max(len(names), 1)
    cols = min(columns, n)
    rows = -(-n // cols)
    fig = new_figure(4.2 * cols, 2.6 * rows)
    for k, name in enumerate(names):
        view = cameras[name]
        uv = np.asarray(view.uv_px, dtype=float).reshape(-1, 2)
        w, h = view.size_px
        ax = fig.add_subplot(rows, cols, k + 1)
        image_outline(ax, view.size_px, "k-")
        ax.plot(uv[:, 0], uv[:, 1], ".", ms=1.2, color="tab:blue", alpha=0.5)
        ax.set_xlim(-10, w + 10)
        ax.set_ylim(h + 10, -10)
        ax.set_aspect("equal")
        ax.set_title(
            f"{name}: {len(uv)} wand points, {view.coverage:.0%} of the image, "
            f"rms {view.rms_px:.3f} px",
            fontsize=8,
        )
        ax.tick_params(labelsize=6)
    return fig


def length_figure(fields: ArrayLike, lengths_mm: ArrayLike, nominal_mm: float) -> Figure:
    """Wand length per field over the trial (left) and its distribution (right).

    Example
    -------
    >>> fig = length_figure([0, 1, 2], [500.1, 499.8, 500.0], 500.0)
    >>> len(fig.axes)
    2
    """
    f = np.asarray(fields, dtype=float)
    d = np.asarray(lengths_mm, dtype=float)
    ok = np.isfinite(d)
    fig = new_figure(9, 2.8)
    ax, hist = fig.subplots(1, 2, width_ratios=(3, 1))
    ax.plot(f[ok], d[ok], ".", ms=2)
    ax.axhline(nominal_mm, color="k", lw=0.8)
    ax.set_xlabel("field")
    ax.set_ylabel("wand length (mm)")
    sd = float(np.std(d[ok], ddof=1)) if ok.sum() > 1 else 0.0
    ax.set_title(
        f"mean {np.mean(d[ok]):.2f} mm, SD {sd:.2f} mm over {int(ok.sum())} fields "
        f"(stated {nominal_mm:g} mm)",
        fontsize=9,
    )
    hist.hist(d[ok] - nominal_mm, bins=30, orientation="horizontal", color="tab:blue")
    hist.set_ylabel("error (mm)")
    hist.set_xlabel("fields")
    return fig
