"""Rigid geometry of labelling: Kabsch fits, rigid correspondences, MDS, the swap search."""

import numpy as np
import pytest

from kisscal.tracking.rigid import (
    _cycle_changes,
    classical_mds,
    kabsch,
    match_to_template,
    mirror_permutation,
    refine_by_swaps,
    rigid_matches,
)
from tests.tracking._data import NAMES, rotation, template


def test_kabsch_recovers_a_properrotation():
    rng = np.random.default_rng(0)
    pts = rng.normal(0, 100, (10, 3))
    r = rotation(2, 40) @ rotation(0, 75)
    moved = pts @ r.T + [5, -7, 300]
    r_est, t_est = kabsch(pts, moved)
    np.testing.assert_allclose(r_est, r, atol=1e-9)
    np.testing.assert_allclose(t_est, [5, -7, 300], atol=1e-7)


def test_classical_mds_reproduces_distances():
    pts = np.random.default_rng(1).normal(0, 50, (8, 3))
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    e = classical_mds(d)
    np.testing.assert_allclose(np.linalg.norm(e[:, None] - e[None], axis=2), d, atol=1e-8)


def test_swap_search_recovers_names_needing_exchanges_and_cycles():
    rng = np.random.default_rng(1)
    template = rng.normal(0, 300, (15, 3))
    tdist = np.linalg.norm(template[:, None] - template[None], axis=2)
    truth = rng.permutation(15)[:12]
    d = tdist[np.ix_(truth, truth)] + rng.normal(0, 1, (12, 12))
    d = (d + d.T) / 2
    np.fill_diagonal(d, 0)
    w = rng.random((12, 12))
    w = (w + w.T) / 2
    np.fill_diagonal(w, 0)

    def cost(q):
        return float((w * (d - tdist[np.ix_(q, q)]) ** 2).sum())

    start = truth.copy()
    rng.shuffle(start)
    # The closed-form change of a 3-cycle equals the recomputed cost change.
    wd = w * d
    tp = tdist[:, start]
    g = (wd * d).sum(1)[:, None] - 2 * wd @ tp.T + w @ (tp.T**2)
    t_ab = tdist[np.ix_(start, start)]
    pair = 2 * (g[:, start] - np.diagonal(g[:, start])[:, None] + w * ((d - t_ab) ** 2 - d**2))
    cyc = _cycle_changes(w, d, pair, t_ab)
    q = start.copy()
    q[3], q[7], q[5] = start[7], start[5], start[3]
    assert cyc[3, 7, 5] == pytest.approx(cost(q) - cost(start), abs=1e-6)
    out = refine_by_swaps(d, w, tdist, start)
    np.testing.assert_array_equal(out, truth)


def test_rigid_match_finds_the_correspondence_under_any_rotation_with_outliers():
    rng = np.random.default_rng(4)
    tmpl = template()
    r = rotation(2, 200.0) @ rotation(0, 30.0)
    pick = rng.permutation(15)[:11]
    pts = tmpl[pick] @ r.T + [900.0, -40.0, 15.0] + rng.normal(0, 2.0, (11, 3))
    pts = np.vstack([pts, pts.mean(axis=0) + [0.0, 0.0, 700.0]])  # 700 mm off the body: no name
    assign, rms = match_to_template(pts, tmpl, 120.0)
    np.testing.assert_array_equal(assign, [*pick, -1])
    assert rms < 5.0
    found = rigid_matches(pts, tmpl, 120.0)
    assert len({tuple(a) for a, _ in found}) == len(found)  # distinct, best first
    assert np.array_equal(found[0][0], assign)


def test_mirror_permutation_exchanges_left_and_right():
    mirror = mirror_permutation(template(), 120.0)
    assert [NAMES[j] for j in mirror] == [
        n if n == "SACR" else {"L": "R", "R": "L"}[n[0]] + n[1:] for n in NAMES
    ]
    lopsided = template().copy()
    lopsided[2] += [0.0, 200.0, 0.0]  # LASI far out: no mirror symmetry
    assert mirror_permutation(lopsided, 120.0) is None
