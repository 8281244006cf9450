"""Figures of a grid linearisation."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from kisscal.grid import linearise_dots
from kisscal.report.grid import grid_correction_figure
from tests.grid.grid_synth import make_grid_view


def test_figure_shows_dots_vectors_and_lines(tmp_path):
    view = make_grid_view(seed=31)
    dots = np.vstack([view.dots_uv[1:], [[5.0, 5.0]]])  # one missing dot, one extra blob
    fit = linearise_dots(dots, size_px=(752, 291))
    fig = grid_correction_figure(fit, "cam1", size_px=(752, 291))
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == [
        "distorted dots", "corrected dots", "correction x 5", "missing dot", "rejected blob",
    ]  # fmt: skip
    quiver = fig.axes[1].collections[0]  # residual vectors
    assert len(quiver.get_offsets()) == fit.index.n_indexed
    fig.savefig(tmp_path / "grid.png")
    q = fit.linearisation.quality  # the corrected rows and columns are straighter
    assert q.straightness_rms_after_px < q.straightness_rms_before_px
    assert (tmp_path / "grid.png").stat().st_size > 10_000
