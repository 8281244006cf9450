"""Epipolar geometry from DLT: true correspondences lie on their lines, offsets are measured."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.errors import KisscalError
from kisscal.recon.epipolar import (
    all_fundamentals,
    camera_centre_mm,
    candidate_pairs,
    distance_matrix_px,
    epipolar_lines,
    fundamental_from_dlt,
    pair_distances_px,
)

from .rig import make_rig, random_markers


def test_true_correspondences_lie_on_epipolar_lines() -> None:
    dlts = make_rig(1)
    xyz = random_markers(np.random.default_rng(0), 1, 50)[0]
    for i in range(6):
        for j in range(6):
            if i == j:
                continue
            F = fundamental_from_dlt(dlts[i], dlts[j])
            d_j, d_i = pair_distances_px(F, project(dlts[i], xyz), project(dlts[j], xyz))
            assert d_j.max() < 1e-6 and d_i.max() < 1e-6
            assert np.linalg.matrix_rank(F, tol=1e-9) == 2


def test_lines_pass_through_the_epipole_and_measure_perpendicular_offsets() -> None:
    dlts = make_rig(2)
    F = fundamental_from_dlt(dlts[0], dlts[3])
    epipole = project(dlts[3], camera_centre_mm(dlts[0]))
    xyz = random_markers(np.random.default_rng(1), 1, 20)[0]
    lines = epipolar_lines(F, project(dlts[0], xyz))
    assert np.allclose(lines[:, :2] @ epipole + lines[:, 2], 0, atol=1e-6)
    # move the true image point 2.5 px along the line normal: distance must read 2.5 px
    uv_j = project(dlts[3], xyz) + 2.5 * lines[:, :2]
    d_j, _ = pair_distances_px(F, project(dlts[0], xyz), uv_j)
    assert np.allclose(d_j, 2.5, atol=1e-6)


def test_distance_matrix_agrees_with_pairwise_distances() -> None:
    dlts = make_rig(3)
    rng = np.random.default_rng(2)
    uv_i = rng.random((7, 2)) * [752, 291]
    uv_j = rng.random((5, 2)) * [752, 291]
    F = fundamental_from_dlt(dlts[1], dlts[4])
    D = distance_matrix_px(F, uv_i, uv_j)
    ii, jj = np.meshgrid(np.arange(7), np.arange(5), indexing="ij")
    d_j, d_i = pair_distances_px(F, uv_i[ii.ravel()], uv_j[jj.ravel()])
    assert np.allclose(D.ravel(), np.maximum(d_j, d_i))


def test_candidate_pairs_equal_brute_force() -> None:
    dlts = make_rig(4)
    F = all_fundamentals(dlts)
    rng = np.random.default_rng(3)
    xyz = random_markers(rng, 4, 6)
    rows = []
    for f in range(4):
        for c in range(6):
            uv = project(dlts[c], xyz[f]) + rng.normal(0, 0.3, (6, 2))
            rows += [(f, c, *p) for p in uv[rng.random(6) < 0.8]]
    table = np.array(rows)
    field, camera, uv = table[:, 0].astype(int), table[:, 1].astype(int), table[:, 2:]
    a, b, d = candidate_pairs(field, camera, uv, F, band_px=2.0)
    got = set(zip(a.tolist(), b.tolist(), strict=True))
    want = set()
    for p in range(len(field)):
        for q in range(len(field)):
            if field[p] == field[q] and camera[p] < camera[q]:
                dd = distance_matrix_px(F[camera[p], camera[q]], uv[p : p + 1], uv[q : q + 1])
                if dd[0, 0] < 2.0:
                    want.add((p, q))
    assert got == want
    assert np.all(d < 2.0) and len(got) > 0


def test_shared_centre_is_an_error() -> None:
    dlts = make_rig(0)
    with pytest.raises(KisscalError):
        fundamental_from_dlt(dlts[0], dlts[0])


def test_candidate_pairs_do_not_depend_on_the_chunk_size(monkeypatch: pytest.MonkeyPatch) -> None:
    import kisscal.recon.epipolar as epipolar

    dlts = make_rig(5)
    F = all_fundamentals(dlts)
    rng = np.random.default_rng(5)
    xyz = random_markers(rng, 30, 8)
    field = np.repeat(np.arange(30), 8 * 6)
    camera = np.tile(np.repeat(np.arange(6), 8), 30)
    uv = np.concatenate([project(dlts[c], xyz[f]) for f in range(30) for c in range(6)])
    whole = candidate_pairs(field, camera, uv, F, 3.0)
    monkeypatch.setattr(epipolar, "_CHUNK", 37)
    chunked = candidate_pairs(field, camera, uv, F, 3.0)
    key = lambda r: sorted(zip(r[0].tolist(), r[1].tolist(), strict=True))  # noqa: E731
    assert key(whole) == key(chunked) and len(whole[0]) >= 30 * 8 * 15
