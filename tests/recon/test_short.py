"""Two-camera pieces too short to continue a trajectory (kisscal.recon.short)."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.recon.short import short_pieces

from .rig import make_rig


def test_a_marker_two_cameras_see_for_three_fields_alone_is_found() -> None:
    # four markers that every camera sees walk through 40 fields (a 30 Hz field's step,
    # a gait's sway); marker M, 300 mm beside them and moving with them, is seen by
    # cameras 0 and 1 in fields 20-22 only and by camera 0 alone elsewhere: three
    # positions continue no trajectory and no segment vouches for it, but its pairs
    # share no blob and reproject like a marker (issue 27: lowcost seeds at 30 Hz, a leg
    # seen by two cameras for a tenth of a second)
    dlts = make_rig(3, n_cameras=4)
    n = 40
    t = np.arange(n)[:, None]
    path = [-500.0, 0.0, 800.0] + t * [25.0, 0.0, 0.0] + 30.0 * np.sin(t / 4.0) * [0, 0, 1]
    offsets = np.array(
        [[0.0, 0.0, 0.0], [150.0, 80.0, 0.0], [-120.0, 60.0, 200.0], [40.0, -150.0, 400.0]]
    )
    xyz = np.concatenate([path[:, None] + offsets, (path + [0.0, 300.0, -300.0])[:, None]], 1)
    seen = np.ones((n, 5, 4), dtype=bool)
    seen[:, 4] = False
    seen[:, 4, 0] = True
    seen[20:23, 4, 1] = True
    rng = np.random.default_rng(5)
    f, m, c = np.nonzero(seen)
    uv = np.array([project(dlts[k], xyz[i, j][None])[0] for i, j, k in zip(f, m, c, strict=True)])
    pts = reconstruct_trial(f, c, uv + rng.normal(0.0, 0.05, uv.shape), dlts, rate_hz=30.0)
    d = np.linalg.norm(pts.xyz_mm[:, None] - xyz[pts.field], axis=2)
    assert not np.any(d.min(axis=1) > 10.0), "no ghost point"
    found = np.unique(pts.field[d[:, 4] < 10.0])
    assert np.array_equal(found, [20, 21, 22]), f"M found in fields {found.tolist()}"


def test_only_unshared_pieces_of_three_fields_with_a_markers_residual_are_taken() -> None:
    # known markers step 20 mm a field with residual 0.04 px; candidate pieces step 15 mm
    # (cameras 0 and 1): fields 2-4 at 0.05 px (taken); fields 6-8 with one 0.12 px
    # pair, a crossing's residual over twice the median (not); fields 10-11, two only
    # (not); fields 13-15, whose last pair shares a blob with a rival (not); fields
    # 17-19, 200 mm apart at 19, more than a known marker moves (not)
    kf = np.repeat(np.arange(22), 2)
    kx = np.column_stack([20.0 * kf, np.tile([0.0, 500.0], 22), np.full(44, 900.0)])
    field = np.array([2, 3, 4, 6, 7, 8, 10, 11, 13, 14, 15, 15, 17, 18, 19])
    xyz = np.column_stack([15.0 * field, np.full(15, 250.0), np.full(15, 900.0)])
    xyz[-1, 0] += 200.0
    rms = np.full(15, 0.05)
    rms[4] = 0.12
    a = 2 * np.arange(15)
    b = a + 1
    b[11] = b[10]  # two pairs of field 15 share a blob
    camera = np.tile([0, 1], 15)
    known = (kx, kf, np.full(44, 0.04))
    won = np.zeros(15, dtype=bool)
    got = short_pieces((a, b, xyz, field), rms, won, camera, known, ReconParams())
    assert got.tolist() == [True] * 3 + [False] * 12
