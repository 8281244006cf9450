"""What the report measures from trajectories, against the truth they were built from."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.io.files import read_table
from kisscal.report.figures import MIN_HALF_RANGE_MM, arrow_gain, stick_figure, throw_figure
from kisscal.report.markers import Dense, dense_trajectories, marker_stats, segment_stats
from kisscal.report.validation import stick_length, throw_fit
from kisscal.report.viewer import thin_step, trial_data
from tests.report import _session as truth


@pytest.fixture(scope="module")
def trials(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Dense]:
    root = truth.write_session(tmp_path_factory.mktemp("measures") / "s", n_fields=200).root
    out = {}
    for name in ("walk", "stick", "throw"):
        t = read_table(root / "out" / "trials" / name / "trajectories.csv")
        xyz = np.column_stack([t["x_mm"], t["y_mm"], t["z_mm"]])
        out[name] = dense_trajectories(t["field"], t["track"], t["label"], xyz, t["status"])
    return out


def test_presence_counts_the_gap_and_the_filled_samples(trials: dict[str, Dense]) -> None:
    stats = {m.label: m for m in marker_stats(trials["walk"])}
    gap = truth.GAP_FIELDS[1] - truth.GAP_FIELDS[0]
    assert (stats["B"].gaps, stats["B"].gap_fields) == (1, gap)
    assert stats["B"].coverage == pytest.approx(1 - gap / 200)
    assert stats["C"].filled == len(truth.FILLED_FIELDS) and stats["C"].coverage == 1.0
    assert stats["A"].gaps == 0 and stats["A"].measured == 200


def test_segment_lengths_match_the_rigid_segments(trials: dict[str, Dense]) -> None:
    s = {(x.a, x.b): x for x in segment_stats(trials["walk"], [("A", "B"), ("B", "C"), ("A", "Z")])}
    assert set(s) == {("A", "B"), ("B", "C")}  # a segment to an absent marker is left out
    for key, length in (("A", "B"), truth.SEGMENT_AB_MM), (("B", "C"), truth.SEGMENT_BC_MM):
        assert s[key].mean_mm == pytest.approx(length, abs=0.15)
        # difference of two independent 3D noises, projected on the segment: sqrt(2) sigma
        assert s[key].sd_mm == pytest.approx(np.sqrt(2) * truth.NOISE_MM, rel=0.25)
    # only fields where both ends are measured count: B's gap and C's filled samples
    assert s["A", "B"].samples == 200 - 5 and s["B", "C"].samples == 200 - 5 - 2


def test_stick_length_is_the_true_length(trials: dict[str, Dense]) -> None:
    s = stick_length(trials["stick"], "stick", truth.RATE_HZ)
    assert s is not None and s.samples == 200
    assert s.mean_mm == pytest.approx(truth.STICK_MM, abs=0.1)
    assert s.mean_abs_error_mm < 0.6 and s.sd_mm < 0.6
    # an unnamed trial is recognised by its constant length; a labelled one is not
    assert stick_length(trials["stick"], "t7", truth.RATE_HZ) is not None
    assert stick_length(trials["stick"], "t7", truth.RATE_HZ, named_only=True) is None


def test_independent_markers_are_no_stick(trials: dict[str, Dense]) -> None:
    walk = trials["walk"]
    apart = Dense(walk.labels[:2], walk.xyz_mm[:2].copy(), walk.status[:2])
    apart.xyz_mm[1, :, 0] += np.linspace(0, 300, walk.n_fields)  # B drifts away from A
    assert stick_length(apart, "t3", truth.RATE_HZ) is None


def test_thrown_marker_gives_g(trials: dict[str, Dense]) -> None:
    fit = throw_fit(trials["throw"], "throw", truth.RATE_HZ)
    assert fit is not None
    assert fit.g_m_s2 == pytest.approx(truth.G_M_S2, rel=0.01)
    assert np.abs(fit.acceleration_m_s2[:2]).max() < 0.1  # no horizontal acceleration
    assert fit.rms_mm == pytest.approx(np.sqrt(3) * truth.NOISE_MM, rel=0.3)
    assert throw_fit(trials["throw"], "t9", truth.RATE_HZ) is not None  # recognised by its fit
    assert throw_fit(trials["walk"], "t9", truth.RATE_HZ) is None  # a walk is no parabola


def test_validation_figures_keep_noise_small(trials: dict[str, Dense]) -> None:
    s = stick_length(trials["stick"], "stick", truth.RATE_HZ)
    ax = stick_figure(s).axes[0]
    lo, hi = ax.get_ylim()
    assert lo <= truth.STICK_MM - MIN_HALF_RANGE_MM and hi >= truth.STICK_MM + MIN_HALF_RANGE_MM
    assert [t.get_text() for t in ax.get_legend().get_texts()][-1] == "true 502.5 mm"
    fig = throw_figure(throw_fit(trials["throw"], "throw", truth.RATE_HZ))
    assert "g = 9.8" in fig.get_suptitle()
    lo, hi = fig.axes[1].get_ylim()
    assert hi - lo >= 2 * MIN_HALF_RANGE_MM


def test_arrow_gain_ignores_one_outlier() -> None:
    rng = np.random.default_rng(1)
    residuals = rng.normal(0, 0.01, (300, 2))
    residuals[0] = [5.0, 0.0]  # one wild point must not shrink every arrow to nothing
    gain = arrow_gain(residuals, 20.0)
    drawn = np.hypot(*residuals[1:].T) * gain
    assert np.median(drawn) > 5.0


def test_segment_figure_without_segments_is_skipped() -> None:
    from kisscal.report.tracking import segment_length_figure
    from kisscal.tracking import build_trajectories

    field = np.repeat(np.arange(20), 2)
    xyz = np.zeros((40, 3))
    xyz[1::2, 0] = 500.0
    result = build_trajectories(field, xyz)
    with pytest.raises(KisscalError):
        segment_length_figure(result, [("RKNE", "RANK")])


def test_viewer_data_thins_fields_and_keeps_gaps(trials: dict[str, Dense]) -> None:
    walk = trials["walk"]
    assert thin_step(3, 200, 300) == 2
    data = trial_data("walk", walk, truth.RATE_HZ, [("A", "B")], 300)
    assert data["step"] == 2 and data["frames"] == 100 and data["rate"] == 25.0
    b = np.array(data["xyz"][1], dtype=object).reshape(-1, 3)
    gaps = [f for f in range(100) if b[f, 0] is None]
    assert gaps == [f // 2 for f in range(*truth.GAP_FIELDS) if f % 2 == 0]
    a = np.array(data["xyz"][0], dtype=float).reshape(-1, 3)
    assert np.abs(a - walk.xyz_mm[0, ::2]).max() <= 0.5  # whole millimetres


def test_grid_residual_panel_shows_its_vectors_with_a_key() -> None:
    from kisscal.grid import linearise_dots
    from kisscal.report.grid import grid_correction_figure
    from tests.grid.grid_synth import make_grid_view

    fit = linearise_dots(make_grid_view(seed=31).dots_uv, size_px=(752, 291))
    panel = grid_correction_figure(fit, "cam1", size_px=(752, 291)).axes[1]
    arrows = panel.collections[0]
    drawn = np.hypot(arrows.U, arrows.V)
    spacing = np.sqrt(np.prod(np.ptp(fit.optimal.uv, axis=0)) / len(fit.optimal.uv))
    assert np.percentile(drawn, 95) == pytest.approx(0.6 * spacing, rel=0.01)
    key = [a for a in panel.get_children() if type(a).__name__ == "QuiverKey"]
    assert len(key) == 1 and key[0].text.get_text().endswith(" px")
