"""Acceptance on the synthetic rig's gait (issue 5 "done when"); see measure.py for the
full table over 8 seeds."""

import numpy as np
import pytest

from kisscal.tracking import (
    MEASURED,
    THESIS_MNC,
    THESIS_PNC,
    TrackingParams,
    build_trajectories,
    sweep_noise,
)
from tests.tracking._eval import score
from tests.tracking._rig import rig_gait


def _run(seed, path_mm):
    r = rig_gait(seed, 300, path_mm=path_mm, ghosts_per_field=1.0)
    res = build_trajectories(
        r.field, r.xyz_mm, TrackingParams(), r.names, r.template_mm, r.segments
    )
    return r, res, score(res, r.truth, r.visible, r.names)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_synth_walk_meets_every_bar(seed):
    _, res, s = _run(seed, 3400.0)
    assert s.one_per_marker and s.n_tracks == 15
    assert s.labels_correct == 15
    assert s.identity_switches == 0
    assert s.coverage >= 0.995
    assert s.rmse_measured_mm <= 1.0
    assert np.isnan(s.rmse_filled_mm) or s.rmse_filled_mm <= 5.0
    assert res.labelling.unlabelled == ()


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_walking_out_of_view_keeps_identities_and_reports_leftovers(seed):
    r, res, s = _run(seed, 7000.0)
    assert s.identity_switches == 0
    named = [t for t in range(s.n_tracks) if t not in res.labelling.unlabelled]
    assert len(named) == 15
    assert s.labels_correct == 15  # every named trajectory has the right name
    assert s.coverage_visible >= 0.985
    assert s.rmse_measured_mm <= 1.0
    assert s.rmse_filled_mm <= 5.0
    # Pieces left unnamed are real markers' (reported), not ghosts.
    tr = res.tracks
    for t in res.labelling.unlabelled:
        rows = (tr.track == t) & (tr.status == MEASURED)
        own = r.truth[s.track_marker[t], tr.field[rows]]
        assert np.nanmax(np.linalg.norm(tr.xyz_mm[rows] - own, axis=1)) < 5.0


@pytest.mark.slow
def test_thesis_sweep_on_rig_gait():
    r = rig_gait(1, 300, ghosts_per_field=1.0)
    rows = sweep_noise(r.field, r.xyz_mm, r.segments, names=r.names, template_mm=r.template_mm)
    assert [(x.pnc, x.mnc) for x in rows] == [(p, m) for p in THESIS_PNC for m in THESIS_MNC]
    for row in rows:
        stats = {(s.segment, s.kind): s for s in row.segments}
        assert len(stats) == 2 * len(r.segments)
        for (seg, kind), st in stats.items():
            if kind == "measured":
                # Rigid segments: measured length spread is noise (0.5 mm per axis).
                assert st.sd_mm < 1.5, seg
        if row.pnc >= 0.05:
            # Thesis: Kalman-corrected lengths vary no more than measured ones.
            worse = [
                seg
                for (seg, kind) in stats
                if kind == "corrected"
                and stats[(seg, "corrected")].sd_mm > 1.1 * stats[(seg, "measured")].sd_mm
            ]
            assert not worse
