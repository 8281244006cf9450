"""Lattice indexing against the known row/column of synthetic dots."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.grid import GridParams, index_lattice
from tests.grid.grid_synth import BrownCamera, make_grid_view


@pytest.mark.parametrize(
    ("camera", "roll_deg", "pitch_over_z"),
    [
        (BrownCamera(), 3.0, 0.0455),  # the KISS case: a few px barrel, small roll
        (BrownCamera(k1=-0.15, k2=0.0), 0.0, 0.0455),  # strong barrel, ~16 px at corners
        (BrownCamera(k1=0.12, k2=0.0), -2.0, 0.042),  # pincushion
        (BrownCamera(), 10.0, 0.036),  # rotated 10 degrees (smaller, to stay in view)
        (BrownCamera(), -10.0, 0.036),
    ],
)
def test_every_dot_gets_its_true_row_and_col(camera, roll_deg, pitch_over_z):
    view = make_grid_view(seed=1, camera=camera, roll_deg=roll_deg, pitch_over_z=pitch_over_z)
    index = index_lattice(view.dots_uv)
    assert index.n_indexed == 300 and len(index.missing_rc) == 0 and len(index.rejected) == 0
    np.testing.assert_array_equal(index.row, view.row)
    np.testing.assert_array_equal(index.col, view.col)


def test_missing_dots_are_reported_where_they_are_and_extra_blobs_rejected():
    view = make_grid_view(seed=2)
    rng = np.random.default_rng(2)
    keep = np.ones(300, dtype=bool)
    keep[rng.choice(300, 15, replace=False)] = False  # 5 % missing
    extra = rng.uniform([0, 0], [752, 291], size=(10, 2))
    order = rng.permutation(keep.sum() + 10)  # any input order
    dots = np.vstack([view.dots_uv[keep], extra])[order]
    index = index_lattice(dots)
    true_row = np.concatenate([view.row[keep], np.full(10, -1)])[order]
    true_col = np.concatenate([view.col[keep], np.full(10, -1)])[order]
    # Extra blobs landing within a fraction of a pixel of a true dot position could not be
    # told apart from it; with uniform blobs the chance is negligible at this seed.
    np.testing.assert_array_equal(index.row, true_row)
    np.testing.assert_array_equal(index.col, true_col)
    assert sorted(index.rejected.tolist()) == sorted(np.flatnonzero(true_row < 0).tolist())
    missing = {(int(r), int(c)) for r, c in index.missing_rc}
    assert missing == {
        (int(r), int(c)) for r, c in zip(view.row[~keep], view.col[~keep], strict=True)
    }
    truth = {
        (int(r), int(c)): uv for r, c, uv in zip(view.row, view.col, view.distorted_uv, strict=True)
    }
    err = [
        np.linalg.norm(uv - truth[(int(r), int(c))])
        for (r, c), uv in zip(index.missing_rc, index.missing_uv, strict=True)
    ]
    assert max(err) < 0.3  # a smooth 4th-order fit over (row, col) predicts them


def test_blobs_on_lattice_positions_beyond_the_grid_are_rejected():
    view = make_grid_view(seed=3, pitch_over_z=0.04)
    # a blob one column step to the right of each dot of row 7's last column
    step = view.dots_uv[view.col == 19][7] - view.dots_uv[view.col == 18][7]
    extra = view.dots_uv[view.col == 19][7:9] + step
    index = index_lattice(np.vstack([view.dots_uv, extra]))
    assert index.n_indexed == 300
    assert sorted(index.rejected.tolist()) == [300, 301]
    np.testing.assert_array_equal(index.col[:300], view.col)


def test_too_few_dots_is_a_clear_error():
    view = make_grid_view(seed=4)
    with pytest.raises(KisscalError, match="at least 270"):
        index_lattice(view.dots_uv[:250])
    # enough blobs, but a fifth of them are noise: cannot index 90 %
    rng = np.random.default_rng(4)
    dots = np.vstack([view.dots_uv[:240], rng.uniform([0, 0], [752, 291], size=(60, 2))])
    with pytest.raises(KisscalError, match="could be indexed"):
        index_lattice(dots)


def test_bad_input_is_refused():
    with pytest.raises(KisscalError, match=r"\(N, 2\)"):
        index_lattice(np.zeros((300, 3)))
    dots = make_grid_view().dots_uv.copy()
    dots[5, 0] = np.nan
    with pytest.raises(KisscalError, match="NaN"):
        index_lattice(dots)
    with pytest.raises(KisscalError, match="model"):
        GridParams(model="affine")  # type: ignore[arg-type]


def test_random_views_are_never_mis_indexed():
    """Random lens, roll, tilt and size; 5 % dots lost, dots outside the image lost, 10 blobs.

    Indices are relative (a grid cut at the top is indexed from its first visible row),
    so the check is one common offset for all dots and no blob indexed far from a dot.
    """
    for seed in range(12):
        rng = np.random.default_rng(seed)
        camera = BrownCamera(
            k1=rng.uniform(-0.15, 0.12), k2=0.0, p1=rng.normal(0, 5e-4), p2=rng.normal(0, 5e-4),
            cx=375.5 + rng.normal(0, 10), cy=145 + rng.normal(0, 5),
        )  # fmt: skip
        view = make_grid_view(
            seed=seed, camera=camera, roll_deg=rng.uniform(-10, 10),
            tilt_deg=(rng.uniform(-4, 4), rng.uniform(-4, 4)),
            pitch_over_z=rng.uniform(0.036, 0.0455),
        )  # fmt: skip
        uv = view.dots_uv
        inside = (uv[:, 0] >= 2) & (uv[:, 0] <= 749) & (uv[:, 1] >= 1) & (uv[:, 1] <= 289)
        keep = inside & (rng.random(300) > 0.05)
        if keep.sum() < 280:
            continue
        dots = np.vstack([uv[keep], rng.uniform([0, 0], [751, 290], size=(10, 2))])
        index = index_lattice(dots)
        n = int(keep.sum())
        ok = index.indexed[:n]
        assert ok.mean() > 0.99
        assert len(np.unique(index.row[:n][ok] - view.row[keep][ok])) == 1
        assert len(np.unique(index.col[:n][ok] - view.col[keep][ok])) == 1
        for k in np.flatnonzero(index.indexed[n:]) + n:  # a blob taken for a missing dot
            near = np.linalg.norm(view.distorted_uv - dots[k], axis=1).min()
            assert near < 1.0


def test_square_spacing_whose_nearest_neighbour_flips_between_row_and_column():
    """Square pixels: rows and columns about equally far apart (a square grid seen square
    on); perspective makes the nearest neighbour of some dots the one beside them and of
    the others the one below. With an even split the median of doubled angles averaged
    the two directions into a diagonal and indexing failed (the lowcost synthetic rig)."""
    rng = np.random.default_rng(4)
    r, c = np.divmod(np.arange(300), 20)
    # columns 28 px apart on the left half, 31 px on the right; rows 29.5 px apart: the
    # nearest neighbour is beside 150 dots and below the other 150
    steps = np.where(np.arange(19) <= 8, 28.0, 31.0)
    u = 40.0 + np.r_[0.0, np.cumsum(steps)][c]
    v = 40.0 + 29.5 * r
    dots = np.column_stack([u, v]) + rng.normal(0, 0.05, (300, 2))
    index = index_lattice(dots)
    assert index.n_indexed == 300
    np.testing.assert_array_equal(index.row, r)
    np.testing.assert_array_equal(index.col, c)
