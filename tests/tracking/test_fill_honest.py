"""Fills expect the error of what they rest on (issue 27, lowcost seed 311), against
truth: a chain fill on a partner another fill placed (kisscal.tracking.raychain), a
pattern fill measured following the neighbour it follows (kisscal.tracking.bodyfill),
a depth fill's spline and a spline fill through noisy samples beside their gaps
(kisscal.tracking.fill_depth, kisscal.tracking.bodyfill)."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.bodyfill import fill_candidates
from kisscal.tracking.fill_depth import (
    _depth_spline,
    context_noise,
    depth_error,
    depth_ray_fill,
)
from kisscal.tracking.fill_passes import SECOND_PASS
from kisscal.tracking.fill_runner import second_pass
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.raychain import chain_fill
from kisscal.tracking.tracks import FILLED, FILLED_PATTERN
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_raychain import GAP, _dense, _segment_on_rays, _spare

PARAMS = TrackingParams()


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    ok = np.all(np.isfinite(a), axis=1)
    return float(np.sqrt(np.mean(np.sum((a[ok] - b[ok]) ** 2, axis=1))))


def test_a_chain_fill_on_a_placed_partner_expects_its_error() -> None:
    xyz = rigid_body(seed=3, noise_mm=0.2)
    dense = _dense(_tracks_of(xyz, {3: GAP, 1: GAP, 2: GAP}))
    # marker 0, the one partner seen through the gap, placed there by another fill 4 mm
    # off towards marker 3 (a length error the ray turns into depth), expecting 4 mm
    toward = xyz[3, GAP] - xyz[0, GAP]
    toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    dense[0, GAP] = xyz[0, GAP] + 4.0 * toward
    errors = np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan)
    errors[0, GAP] = 4.0
    spare = _spare(xyz, 3)
    plain = chain_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS)
    got = chain_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, 0, errors)
    assert plain is not None
    true = _rms(plain.xyz_mm, xyz[3, GAP])
    assert true > 3.0  # the placed partner's error carried into the fill
    claim = float(np.sqrt(np.nanmean(plain.sd_mm**2)))
    assert true > 2.0 * claim  # as if measured: dishonest
    # counting the partner's own error (one partner: at least it along the ray): honest
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert np.all(got.sd_mm[placed] >= 4.0)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.all(err <= 2.0 * got.sd_mm[placed])


def _follower(n: int = 400) -> np.ndarray:
    """Three markers at 100 Hz: a target walking and swinging (0); a neighbour that keeps
    its offset from it (1); a farther one whose offset from it swings by 60 mm (2)."""
    t = np.arange(n) / 100.0
    walk = np.column_stack([1200.0 * t, 30.0 * np.sin(2.0 * t), 900.0 + 20.0 * np.sin(12.0 * t)])
    swing = np.column_stack([60.0 * np.sin(6.0 * t), 0 * t, 40.0 * np.cos(6.0 * t)])
    return np.stack([walk, walk + [50.0, 0.0, 0.0], walk + [0.0, 200.0, 0.0] + swing])


def test_a_pattern_fill_is_measured_following_the_neighbour_it_follows() -> None:
    xyz = _follower()
    rng = np.random.default_rng(2)
    dense = xyz + rng.normal(0.0, 0.2, xyz.shape)
    lo, hi = 200, 230
    dense[0, lo:hi] = np.nan
    dense[1, lo - 3 : hi + 3] = np.nan  # the neighbour that follows it is hidden too
    cands = [
        c for c in fill_candidates(dense, 0, lo, hi, PARAMS) if c.fill.status == FILLED_PATTERN
    ]
    assert len(cands) == 1 and cands[0].fill.donors == (2,)
    true = _rms(cands[0].xyz_mm, xyz[0, lo:hi])
    assert true > 5.0  # the swinging neighbour's offset strays from a line
    assert true <= 2.0 * cands[0].fill.expected_error_mm


def test_a_depth_fill_beside_noisy_samples_expects_what_their_noise_carries() -> None:
    xyz = rigid_body(seed=7, noise_mm=0.2)
    gap = slice(100, 116)
    dense = _dense(_tracks_of(xyz, {1: gap, 2: gap, 3: gap}))
    # the six samples each side of the gap 1.5 mm noisy (seen by two cameras there), the
    # rest of the trial's 0.2 mm: the stretches the spline is tried on do not show it
    rng = np.random.default_rng(7)
    for side in (slice(gap.start - 6, gap.start), slice(gap.stop, gap.stop + 6)):
        dense[3, side] += rng.normal(0.0, 1.5, (6, 3))
    spare = _segment_on_rays(xyz, 7, (3,))
    centre = spare.centres[0]
    spline = _depth_spline(dense[3], centre, gap.start, gap.stop, PARAMS.fill_context_fields)
    true = np.sqrt(np.mean((spline - np.linalg.norm(xyz[3, gap] - centre, axis=1)) ** 2))
    assert true > 2.0 * depth_error(dense[3], centre, gap.start, gap.stop, PARAMS)
    # their noise carried into the gap is more than the depth fill may expect: refused
    assert context_noise(dense[3], centre, gap.start, gap.stop, 6) > true / 2.0
    assert depth_ray_fill(dense, 3, gap.start, gap.stop, spare, PARAMS) is None


def test_a_spline_beside_noisy_samples_expects_what_their_noise_carries() -> None:
    xyz = rigid_body(seed=7, noise_mm=0.2)
    gap = slice(100, 105)
    # as the depth fill's: the six samples each side 1.5 mm noisy, the trial's 0.2 mm
    seen = xyz.copy()
    rng = np.random.default_rng(7)
    for side in (slice(gap.start - 6, gap.start), slice(gap.stop, gap.stop + 6)):
        seen[3, side] += rng.normal(0.0, 1.5, (6, 3))
    out, fills = fill_gaps_logged(_tracks_of(seen, {3: gap}), PARAMS)
    (fill,) = fills
    assert fill.status == FILLED and fill.first_field == gap.start
    true = _rms(out.xyz_mm[(out.track == 3) & (out.status == FILLED)], xyz[3, gap])
    assert true > 5.0  # 6.5 mm; before, 0.84 expected from the quiet stretches
    assert true <= 2.0 * fill.expected_error_mm <= 4.0 * true


def test_a_chain_fill_on_noisy_partners_expects_what_its_lengths_miss_beside_the_gap() -> None:
    xyz = rigid_body(seed=3, noise_mm=0.2)
    dense = _dense(_tracks_of(xyz, {3: GAP, 1: GAP, 2: GAP}))
    # marker 0, the partner, 4 mm noisy in and beside the gap (few cameras see it there),
    # 0.2 mm in the rest of the trial: its length's SD over the trial does not show it
    near = slice(GAP.start - 20, GAP.stop + 20)
    dense[0, near] += np.random.default_rng(3).normal(0.0, 4.0, dense[0, near].shape)
    got = chain_fill(dense, 3, GAP.start, GAP.stop, _spare(xyz, 3), PARAMS)
    assert got is not None
    true = _rms(got.xyz_mm, xyz[3, GAP])
    assert true > 3.0  # 4.2 mm; before, 1.4 expected
    assert true <= 2.0 * float(np.sqrt(np.nanmean(got.sd_mm**2)))


def test_the_second_pass_splines_a_short_run_beside_placed_samples_expecting_their_error() -> None:
    xyz = rigid_body(seed=4, noise_mm=0.2)
    run = slice(120, 125)
    # every marker hidden in the run (no body fill); marker 3's six fields before it were
    # placed by a first-pass fill expecting 1.5 mm; one camera sees only noise blobs
    dense = _dense(_tracks_of(xyz, {0: run, 1: run, 2: run, 3: run}))
    errors = np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan)
    errors[3, run.start - 6 : run.start] = 1.5
    f = np.repeat(np.arange(run.start - 10, run.stop + 10), 2)
    uv = np.random.default_rng(4).uniform([0, 0], [640, 480], (f.size, 2))
    spare = spare_blobs(f, np.zeros(f.size), uv, _spare(xyz, 4).dlts)
    measured = np.isfinite(dense[:, :, 0])
    got = second_pass(
        dense, [(3, run.start, run.stop)], PARAMS, spare, measured, [], None, SECOND_PASS, errors
    )
    (fill,) = [g for _, g in got if g.track == 3]  # before, the second pass had no spline
    xyz3 = np.concatenate([x for x, g in got if g.track == 3])
    assert fill.status == FILLED and fill.expected_error_mm >= 1.5
    assert _rms(xyz3, xyz[3, run]) <= 2.0 * fill.expected_error_mm
    # beside samples expecting more than a body fill there may: refused
    errors[3, run.start - 6 : run.start] = 2.0 * PARAMS.ray_rest_max_error_mm
    got = second_pass(
        dense, [(3, run.start, run.stop)], PARAMS, spare, measured, [], None, SECOND_PASS, errors
    )
    assert not [g for _, g in got if g.track == 3]


def test_a_depth_fill_expects_the_error_its_spline_shows_in_the_gap_s_phase() -> None:
    # kiss 3 seed 302's tibia: the runs beside the gap too short for a whole stretch, the
    # two found 350 fields away in smooth motion (0.4, 1.6 mm); 2.9 mm off expecting 1.2
    f = np.arange(400)
    centre = np.array([0.0, -3000.0, 1000.0])
    sight = np.stack([np.sin(f / 400), np.cos(f / 400), np.full(f.size, -0.3)], 1)
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    # the depth jerks every 8 fields in the first 70 (the gap's phase), smooth after
    depth = 3000.0 + 2.0 * f
    depth += sum(3.0 * np.exp(-0.5 * ((f - c) / 1.5) ** 2) for c in np.arange(1.5, 70, 8))
    series = np.full((f.size, 3), np.nan)
    for a, b in ((0, 18), (26, 39), (96, 122), (300, 400)):
        series[a:b] = centre + depth[a:b, None] * sight[a:b]
    lo, hi = 18, 26
    spline = _depth_spline(series, centre, lo, hi, PARAMS.fill_context_fields)
    true = float(np.sqrt(np.mean((spline - depth[lo:hi]) ** 2)))
    assert true > 3.0  # 3.3 mm
    assert true <= 2.0 * depth_error(series, centre, lo, hi, PARAMS)  # before, 0.0
