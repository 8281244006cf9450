"""The gait-cycle figure draws every event it is given."""

from __future__ import annotations

from kisscal.gait import gait_cycle_figure
from tests.gait import _synth


def test_figure_marks_detected_and_true_events() -> None:
    tr = _synth.trial(11, 100.0, 300.0, 1.65, 1.1, duration_s=3.0)
    fig = gait_cycle_figure(tr.markers, tr.events, tr.truth.events, title="synthetic")
    assert len(fig.axes) == 4
    for col, side in enumerate(("left", "right")):
        n_found = sum(s == side for s in tr.events.side)
        n_true = sum(s == side for s in tr.truth.events.side)
        for ax in (fig.axes[col], fig.axes[2 + col]):
            assert len(ax.lines) - (3 if ax is fig.axes[2 + col] else 2) == n_found + n_true
    assert fig._suptitle.get_text() == "synthetic"
