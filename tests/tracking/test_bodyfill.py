"""Gap filling from the body (kisscal.tracking.bodyfill) against truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kisscal.io.trajectories import read_trajectories_csv, write_trajectories_csv
from kisscal.tracking import (
    FILLED,
    FILLED_PATTERN,
    FILLED_RIGID,
    MEASURED,
    STATUS_NAMES,
    TrackingParams,
    is_filled,
)
from kisscal.tracking.bodyfill import (
    MutualSD,
    axis_fill,
    best_candidate,
    distance_sd,
    fill_candidates,
    pattern_fill,
    rigid_fill,
    segment_carriers,
)
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.tracks import make_tracks

N = 300


def rigid_body(seed: int = 0, noise_mm: float = 0.0) -> np.ndarray:
    """Four markers of one rigid body turning and moving: (4, N, 3)."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) / 100.0
    rot = Rotation.from_rotvec(np.stack([0.5 * np.sin(2 * t), 0.3 * np.cos(3 * t), t], 1))
    shape = np.array([[0.0, 0, 0], [100, 0, 0], [0, 80, 0], [30, 20, 60]])
    move = np.stack([500 * t, 100 * np.sin(t), 900 + 0 * t], 1)
    xyz = np.stack([rot.apply(p) + move for p in shape])
    return xyz + rng.normal(0, noise_mm, xyz.shape)


def test_rigid_fill_restores_a_rigid_body_marker_over_a_long_gap():
    xyz = rigid_body()
    cut = xyz.copy()
    cut[3, 100:200] = np.nan  # 1 s at 100 Hz, the body turning through it
    got = rigid_fill(cut[3], cut, 3, 100, 200, TrackingParams())
    assert got is not None
    assert sorted(got[1]) == [0, 1, 2]
    assert np.abs(got[0] - xyz[3, 100:200]).max() < 1e-6


def test_carriers_are_chosen_from_the_distance_sds_they_need_only():
    # Two rigid bodies and a wanderer: MutualSD computes the columns segment_carriers
    # reads, bit for bit those of the whole c x c matrix, and no others.
    other = rigid_body(1, 0.5)[:, ::-1] + 200.0
    wander = rigid_body(2)[:1] + np.random.default_rng(3).normal(0, 30, (1, N, 3))
    dense = np.concatenate([rigid_body(0, 0.3), other, wander])
    dense[2:5, 40:90] = np.nan
    cand = np.arange(1, len(dense))
    params = TrackingParams()
    to_target = distance_sd(dense[cand], dense[:1])[:, 0]
    full = distance_sd(dense[cand], dense[cand])
    lazy = MutualSD(dense[cand])
    chosen, weight = segment_carriers(to_target, lazy, params)
    assert len(chosen) >= 2 and 0 < len(lazy.done) < len(cand)
    assert all(np.array_equal(full[:, j], sd) for j, sd in lazy.done.items())
    assert chosen == segment_carriers(to_target, full, params)[0]
    assert np.array_equal(weight, segment_carriers(to_target, full, params)[1])


def test_rigid_fill_needs_two_markers_of_the_segment():
    xyz = rigid_body()
    # marker 2 swings away from the others: only marker 0 and 1 stay rigid with 3
    t = np.arange(N)
    xyz[2] += np.stack([40 * np.sin(t / 10), 0 * t, 0 * t], 1)
    xyz[1] += np.stack([0 * t, 40 * np.sin(t / 7), 0 * t], 1)
    cut = xyz.copy()
    cut[3, 100:200] = np.nan
    assert rigid_fill(cut[3], cut, 3, 100, 200, TrackingParams()) is None


def pelvis(yaw_deg: float = 40.0, tilt_deg: float = 2.0) -> np.ndarray:
    """Three markers of a pelvis-like segment walking and turning (yaw up to ``yaw_deg``)
    while tilting little about the axis of markers 0 and 1: (3, N, 3)."""
    t = np.arange(N) / 100.0
    yaw = np.radians(yaw_deg) * np.sin(1.5 * t)
    tilt = np.radians(tilt_deg) * np.sin(6 * t)
    rot = Rotation.from_euler("zy", np.stack([yaw, tilt], 1))
    shape = np.array([[100.0, -120, 990], [100, 120, 990], [-110, 0, 1010]])
    move = np.stack([1200 * t, 20 * np.sin(6 * t), 0 * t], 1)
    return np.stack([rot.apply(p) + move for p in shape])


def test_two_marker_fill_carries_a_pelvis_marker_that_turns():
    """Two of three pelvis markers in view: rigid-body fill needs three, pattern fill
    misses the turn, the two markers' frame follows it (its turn about their axis, the
    tilt, is what it cannot see)."""
    xyz = pelvis()
    cut = xyz.copy()
    cut[2, 100:200] = np.nan
    params = TrackingParams()
    assert rigid_fill(cut[2], cut, 2, 100, 200, params) is None
    got = axis_fill(cut[2], cut, 2, 100, 200, params)
    assert got is not None and sorted(got[1]) == [0, 1]
    err = np.linalg.norm(got[0] - xyz[2, 100:200], axis=1)
    follow = pattern_fill(cut[2], cut, 2, 100, 200, params)
    assert follow is not None
    # at most about the tilt's swing at the marker's 210 mm from the axis
    assert err.max() < 1.5 * 210 * np.sin(np.radians(2.0))
    assert err.max() < 0.5 * np.linalg.norm(follow[0] - xyz[2, 100:200], axis=1).max()


def test_two_marker_fill_refuses_markers_of_other_segments():
    xyz = pelvis()
    t = np.arange(N)
    xyz[1] += np.stack([30 * np.sin(t / 9), 0 * t, 0 * t], 1)  # not rigid with the others
    cut = xyz.copy()
    cut[2, 100:200] = np.nan
    assert axis_fill(cut[2], cut, 2, 100, 200, TrackingParams()) is None


def test_pattern_fill_follows_the_neighbour():
    xyz = rigid_body()
    # marker 3 follows marker 0 at an offset drifting slowly (soft tissue)
    drift = np.linspace(0, 5, N)[:, None] * np.array([1.0, 0, 0])
    xyz[3] = xyz[0] + np.array([20.0, 10, 5]) + drift
    cut = xyz.copy()
    cut[3, 120:180] = np.nan
    got = pattern_fill(cut[3], cut, 3, 120, 180, TrackingParams())
    assert got is not None and got[1] == (0,)
    assert np.abs(got[0] - xyz[3, 120:180]).max() < 1e-6


def test_body_fill_measures_its_expected_error_and_it_holds():
    xyz = rigid_body(seed=3, noise_mm=0.5)
    cut = xyz.copy()
    cut[3, 100:200] = np.nan
    best = best_candidate(fill_candidates(cut, 3, 100, 200, TrackingParams()), TrackingParams())
    filled, how = best.xyz_mm, best.fill
    true_rms = np.sqrt(np.mean(np.sum((filled - xyz[3, 100:200]) ** 2, axis=1)))
    assert how.status == FILLED_RIGID
    assert true_rms < 1.5
    # measured beside the gap, the expected error is of the size of the true one
    assert 0.2 * true_rms < how.expected_error_mm < 5 * true_rms + 1.0


def _tracks_of(xyz: np.ndarray, hidden: dict[int, slice]) -> object:
    n_tracks, n, _ = xyz.shape
    keep = np.ones((n_tracks, n), dtype=bool)
    for t, s in hidden.items():
        keep[t, s] = False
    tr, f = np.nonzero(keep)
    return make_tracks(
        f, tr, xyz[tr, f], np.full((tr.size, 3), np.nan), np.zeros(tr.size), np.arange(tr.size)
    )


def test_fill_gaps_spline_for_short_gaps_body_for_long_and_statuses_say_so():
    xyz = rigid_body(seed=1, noise_mm=0.2)
    tracks = _tracks_of(xyz, {3: slice(200, 203), 2: slice(60, 160)})
    out, fills = fill_gaps_logged(tracks, TrackingParams())
    how = {(g.track, g.first_field): g for g in fills}
    assert how[(3, 200)].status == FILLED and how[(3, 200)].n_fields == 3
    assert how[(2, 60)].status in (FILLED_RIGID, FILLED_PATTERN)
    assert np.isfinite(how[(2, 60)].expected_error_mm)
    dense = out.positions()
    assert np.all(np.isfinite(dense))  # every gap filled
    err = np.linalg.norm(dense - xyz, axis=2)
    filled = np.zeros(dense.shape[:2], dtype=bool)
    filled[out.track[is_filled(out.status)], out.field[is_filled(out.status)]] = True
    assert np.sqrt(np.mean(err[filled] ** 2)) < 3.0


def test_gaps_beyond_the_body_limit_stay_open():
    xyz = rigid_body()
    tracks = _tracks_of(xyz, {3: slice(50, 250)})
    out, _ = fill_gaps_logged(tracks, TrackingParams(max_body_fill_fields=100))
    assert not is_filled(out.status).any()
    assert (out.status == MEASURED).sum() == tracks.field.size


def test_status_names_round_trip_and_legacy_filled_reads_as_spline(tmp_path):
    xyz = rigid_body()
    tracks = _tracks_of(xyz, {3: slice(200, 203), 2: slice(60, 160)})
    out, _ = fill_gaps_logged(tracks, TrackingParams())
    path = write_trajectories_csv(tmp_path / "t.csv", out, ("A", "B", "C", "D"))
    table = read_trajectories_csv(path)
    assert np.array_equal(table.status, out.status)
    assert set(np.asarray(STATUS_NAMES)[table.status]) >= {"measured", "filled_spline"}
    old = path.read_text().replace("filled_spline", "filled")
    (tmp_path / "old.csv").write_text(old)
    assert np.array_equal(read_trajectories_csv(tmp_path / "old.csv").status, out.status)


@pytest.mark.parametrize("bad", [{"rigid_fill_markers": 2}, {"rigid_fill_sd_mm": 0.0}])
def test_bad_body_fill_params_are_refused(bad):
    from kisscal.errors import KisscalError

    with pytest.raises(KisscalError, match=r"\[tracking\]"):
        TrackingParams(**bad)
