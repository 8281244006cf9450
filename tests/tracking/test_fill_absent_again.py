"""A name no track took, tried again once its partners are placed on their rays
(kisscal.tracking.fill_absent_again.absent_named), and a missing name that moves with its
exchanged pair (kisscal.tracking.labelling.sides), against truth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_absent import absent_placed
from kisscal.tracking.fill_absent_again import AbsentContext, absent_named
from kisscal.tracking.gaps import fill_gaps_named
from kisscal.tracking.labelling.anatomy import Anatomy
from kisscal.tracking.labelling.sides import judge_sides
from kisscal.tracking.tracks import FILLED_RIGID, MEASURED
from tests.tracking.test_anatomy import LOWER, PIG, _labelling, walker
from tests.tracking.test_bodyfill import _tracks_of
from tests.tracking.test_fill_absent import GAP, LABELS, PARAMS, _cameras, _feet
from tests.tracking.test_raychain import _dense

#: The right toe and tibia measured in the first fields only (tracks 5 and 6).
HIDDEN = slice(6, None)
#: A piece of the right ankle measured in the first 5 fields only.
THIN = slice(5, None)


def _named(seed: int, filled: bool) -> tuple[list[str], list, np.ndarray]:
    """The right ankle, which camera 0 sees all trial, named by :func:`absent_named`
    with the toe and tibia measured in 6 fields (too few to name it by), and, with
    ``filled``, placed on rays in the rest (expecting 1 mm, 0.5 mm off)."""
    right, truth = _feet(seed)
    dense = _dense(_tracks_of(truth, {5: HIDDEN, 6: HIDDEN}))
    spare = _cameras(right, seed, HIDDEN)
    first = absent_placed(dense, LABELS, ("RANK",), spare, PARAMS)
    assert 0 < np.isfinite(first[1][0, :, 0]).sum() < PARAMS.min_track_length
    rng = np.random.default_rng(seed)
    n = truth.shape[1] - HIDDEN.start
    made = (
        [
            (
                truth[t, HIDDEN] + rng.normal(0, 0.3, (n, 3)),
                GapFill(t, HIDDEN.start, n, FILLED_RIGID, 1.0, (4,), n),
            )
            for t in (5, 6)
        ]
        if filled
        else []
    )
    measured = np.isfinite(dense[..., 0])
    ctx = AbsentContext(dense, measured, made, LABELS, first, ("RANK",), spare, PARAMS)
    names, out = absent_named(ctx)
    return names, out, right[2]


def test_an_absent_ankle_is_named_once_its_partners_are_placed_on_rays():
    # kiss 3 seed 414: a knee one camera sees all trial, its tibia and ankle measured
    # together in 23 fields and placed on rays in 226
    names, _, _ = _named(27, filled=False)
    assert names == []  # placed too short to be named
    names, out, truth = _named(27, filled=True)
    assert names == ["RANK"]
    assert all(g.track == len(LABELS) and g.status == FILLED_RIGID for _, g in out)
    f = np.concatenate([g.first_field + np.arange(g.n_fields) for _, g in out])
    assert f.size > 0.8 * truth.shape[0]
    err = np.linalg.norm(np.concatenate([x for x, _ in out]) - truth[f], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0 and err.max() < 5.0
    for x, g in out:  # each run's expected error is honest
        miss = np.linalg.norm(x - truth[g.first_field : g.first_field + g.n_fields], axis=1)
        assert np.sqrt(np.mean(miss**2)) <= 2.0 * max(g.expected_error_mm, 0.5)


def test_a_missing_name_moves_with_its_exchanged_pair():
    # kiss 3 seed 414: the left knee's trajectory named RKNE, the right knee never seen;
    # the exchange names it LKNE, and RKNE is the name left for fill_absent to place
    pos = walker(5, 20.0)
    left, right = LOWER.index("LKNE"), LOWER.index("RKNE")
    keep = [i for i in range(len(LOWER)) if i != right]
    labels = tuple("RKNE" if i == left else LOWER[i] for i in keep)
    labelling = replace(_labelling(pos[keep], labels), missing=("LKNE",))
    judged = judge_sides(labelling, Anatomy.of_set(PIG), PIG.template_mm, 50.0, TrackingParams())
    assert judged.exchanged == (("LKNE", "RKNE"),)
    assert judged.labels == tuple(LOWER[i] for i in keep)
    assert judged.missing == ("RKNE",)


def test_a_named_piece_too_short_to_know_its_lengths_is_placed_beside_its_samples():
    # kiss 3 seed 439: a 5-field piece named LANK, the ankle one camera sees in 278
    right, truth = _feet(28)
    labels = (*LABELS, "RANK")
    tracks = _tracks_of(np.concatenate([truth, right[2][None]]), {5: GAP, 6: GAP, 7: THIN})
    spare = _cameras(right, 28, GAP)
    out, fills = fill_gaps_named(tracks, PARAMS, spare, labels, (), ())[:2]
    rows = out.track == 7
    assert np.sum(rows & (out.status == MEASURED)) == THIN.start  # its samples kept
    placed = rows & (out.status == FILLED_RIGID)
    assert placed.sum() > 0.8 * (truth.shape[1] - (GAP.stop - GAP.start))
    err = np.linalg.norm(out.xyz_mm[placed] - right[2, out.field[placed]], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0 and err.max() < 5.0
    assert np.unique(out.field[rows]).size == rows.sum()  # one sample a field
    for g in (g for g in fills if g.track == 7):  # each run's expected error is honest
        f = (out.field[rows] >= g.first_field) & (out.field[rows] < g.first_field + g.n_fields)
        miss = np.linalg.norm(out.xyz_mm[rows][f] - right[2, out.field[rows][f]], axis=1)
        assert np.sqrt(np.mean(miss**2)) <= 2.0 * max(g.expected_error_mm, 0.5)
