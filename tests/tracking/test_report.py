import io

import numpy as np

from kisscal.report.tracking import segment_length_figure, trajectories_figure
from kisscal.tracking import TrackingParams, build_trajectories
from tests.tracking._data import NAMES, SEGMENTS, gait_truth, observe, template


def _result():
    truth = gait_truth(100, 2)
    field, xyz, _, _ = observe(truth, 2, noise_mm=0.5, ghosts_per_field=0.3)
    return build_trajectories(field, xyz, TrackingParams(), NAMES, template())


def test_figures_render_with_one_line_per_track_and_segment():
    res = _result()
    fig = trajectories_figure(res, title="walk")
    axes = fig.get_axes()
    assert len(axes) == 3
    assert (
        len([ln for ln in axes[0].get_lines() if ln.get_linestyle() == "-"]) == res.tracks.n_tracks
    )
    # The top view shows X against Y of the data.
    line = axes[0].get_lines()[0]
    x = np.asarray(line.get_xdata(), dtype=float)
    assert np.nanmax(x) == np.nanmax(res.tracks.xyz_mm[res.tracks.track == 0, 0])
    seg = segment_length_figure(res, SEGMENTS, 50.0)
    assert len(seg.get_axes()) == len(SEGMENTS)
    length = np.asarray(seg.get_axes()[0].get_lines()[0].get_ydata(), dtype=float)
    assert np.nanstd(length) < 3.0  # RKNE-RANK keeps its length
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    assert buf.getvalue()[:4] == b"\x89PNG"
