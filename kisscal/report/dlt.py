"""Figures of the DLT calibration: residual vectors per camera, cameras and rods in 3D.

Figures are built with :class:`matplotlib.figure.Figure` (no pyplot state, Agg canvas),
so they are safe in tests and batch runs; save them with ``fig.savefig(path)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from kisscal._shared import fixed_margins, new_figure
from kisscal.report.figures import arrow_gain, image_outline, nice_number, scale_key

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class CameraResiduals:
    """What the residual figure shows for one camera.

    Attributes
    ----------
    uv_px : array_like, shape (N, 2)
        Control point image positions (pixels).
    residuals_px : array_like, shape (N, 2)
        Observed - projected (pixels).
    size_px : tuple of int
        Image width and height (pixels).
    rms_px : float
        sqrt(mean(du^2 + dv^2)).
    """

    uv_px: ArrayLike
    residuals_px: ArrayLike
    size_px: tuple[int, int]
    rms_px: float


def residual_figure(cameras: Mapping[str, CameraResiduals]) -> Figure:
    """Residual vectors of every camera's control points, drawn in the image frame, two
    panels a row. The 95th-percentile residual of all cameras is drawn 40 px long, the
    same scale in every panel, and each panel has a key arrow giving it in pixels.

    Parameters
    ----------
    cameras : mapping
        Camera id -> :class:`CameraResiduals`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = list(cameras)
    n = max(len(names), 1)
    cols = min(2, n)
    rows = -(-n // cols)
    size = (5.5 * cols, 2.8 * rows)
    fig = new_figure(*size, constrained=False)
    fig.subplots_adjust(**fixed_margins(size, (rows, cols), (0.45, 0.1, 0.3, 0.3), (0.5, 0.5)))
    every = [np.asarray(c.residuals_px, dtype=float).reshape(-1, 2) for c in cameras.values()]
    scale = arrow_gain(np.concatenate(every) if every else np.zeros((0, 2)), 40.0)
    key = nice_number(40.0 / scale)
    for k, name in enumerate(names):
        c = cameras[name]
        ax = fig.add_subplot(rows, cols, k + 1)
        uv = np.asarray(c.uv_px, dtype=float).reshape(-1, 2)
        r = np.asarray(c.residuals_px, dtype=float).reshape(-1, 2)
        w, h = c.size_px
        image_outline(ax, c.size_px, "k-", lw=0.5)
        ax.plot(uv[:, 0], uv[:, 1], "o", ms=2.5, color="tab:blue")
        to_scale = {"angles": "xy", "scale_units": "xy", "scale": 1}  # arrows in data px
        arrows = ax.quiver(*uv.T, *(r * scale).T, **to_scale, color="tab:red", width=0.004)
        ax.set_xlim(-10, w + 10)
        ax.set_ylim(h + 10, -10)  # image y axis points down
        ax.set_aspect("equal")
        scale_key(ax, arrows, key * scale, f"{key:g} px")
        ax.set_title(
            f"{name}: rms {c.rms_px:.3f} px, {len(uv)} points, arrows x{scale:.0f}", fontsize=9
        )
        ax.tick_params(labelsize=7)
    return fig


def rig_figure(
    centres_mm: Mapping[str, ArrayLike],
    rods_mm: Sequence[tuple[str, ArrayLike]],
    rotations: Mapping[str, ArrayLike] | None = None,
    reconstructed_mm: ArrayLike | None = None,
) -> Figure:
    """Cameras and calibration rods in the lab frame (3D).

    Parameters
    ----------
    centres_mm : mapping
        Camera id -> projection centre (mm).
    rods_mm : sequence of (name, points_mm (k, 3))
        Surveyed rod markers.
    rotations : mapping, optional
        Camera id -> rotation lab -> camera; the optical axis is drawn (600 mm) when given.
    reconstructed_mm : array_like, shape (M, 3), optional
        Reconstructed rod markers, drawn as crosses over the surveyed ones.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(7, 6, constrained=False)
    ax = fig.add_subplot(projection="3d")
    for name, pts in rods_mm:
        p = np.asarray(pts, dtype=float)
        ax.plot(p[:, 0], p[:, 1], p[:, 2], "-o", ms=3, lw=1)
        ax.text(*p[0], name, fontsize=8)
    for cam, c in centres_mm.items():
        c = np.asarray(c, dtype=float)
        ax.scatter(*c, marker="s", s=25, color="k")
        ax.text(*c, f" {cam}", fontsize=8)
        if rotations is not None and cam in rotations:
            axis = np.asarray(rotations[cam], dtype=float)[2] * 600.0
            ax.plot(*np.stack([c, c + axis]).T, color="tab:gray", lw=1)
    if reconstructed_mm is not None:
        q = np.asarray(reconstructed_mm, dtype=float).reshape(-1, 3)
        ax.scatter(q[:, 0], q[:, 1], q[:, 2], marker="x", s=20, color="tab:red")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_zlabel("Z (mm)")
    pts = [np.asarray(p, dtype=float) for _, p in rods_mm]
    pts += [np.asarray(c, dtype=float)[None] for c in centres_mm.values()]
    if pts:
        allp = np.concatenate(pts)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        ax.set_box_aspect(np.maximum(hi - lo, 1.0))
    ax.set_title("Cameras and calibration rods (lab frame)")
    return fig
