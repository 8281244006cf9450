"""The key arrow of a residual panel covers neither the panel's title nor its data."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from kisscal.report.dlt import CameraResiduals, residual_figure


def _key_clear(ax: Axes, data_v: np.ndarray) -> None:
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    fig.draw_without_rendering()
    key = next(a for a in ax.get_children() if type(a).__name__ == "QuiverKey")
    label = key.text.get_window_extent(renderer)
    for title in (ax.title, ax._left_title):  # centred (DLT) or left (grid)
        if title.get_text():
            assert not label.overlaps(title.get_window_extent(renderer)), title.get_text()
    panel = ax.get_window_extent(renderer)
    assert panel.x0 <= label.x0 and label.x1 <= panel.x1 + 2
    assert panel.y0 <= label.y0 and label.y1 <= panel.y1
    # the key stands below every data point (v down: beyond the largest v)
    _, key_v = ax.transData.inverted().transform(ax.transAxes.transform((key.X, key.Y)))
    assert key_v > data_v.max()


def test_dlt_residual_panels() -> None:
    rng = np.random.default_rng(3)
    cams = {}
    for k in range(4):  # long titles and points up to the image's bottom edge
        uv = np.column_stack([rng.uniform(0, 752, 30), rng.uniform(0, 291, 30)])
        uv[0] = (740, 290)
        cams[f"camera-{k}-with-a-long-name"] = CameraResiduals(
            uv, rng.normal(0, 0.1, (30, 2)), (752, 291), 0.141
        )
    fig = residual_figure(cams)
    for ax, c in zip(fig.axes, cams.values(), strict=True):
        _key_clear(ax, np.asarray(c.uv_px)[:, 1])


def test_grid_residual_panel() -> None:
    from kisscal.grid import linearise_dots
    from kisscal.report.grid import grid_correction_figure
    from tests.grid.grid_synth import make_grid_view

    fit = linearise_dots(make_grid_view(seed=31).dots_uv, size_px=(752, 291))
    panel = grid_correction_figure(fit, "cam1", size_px=(752, 291)).axes[1]
    _key_clear(panel, np.r_[fit.optimal.uv[:, 1], 290.5])
