"""Lost markers carried by a marker of their rigid body (kisscal.recon.carried)."""

from __future__ import annotations

import numpy as np

from kisscal.recon.carried import carried, links


def _walk(n: int, lost: int = 10) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Markers A (lost from field ``lost`` on) and S of one rigid body bobbing as it walks,
    and C beside A swinging (not rigid with it). Returns the points, their fields, their
    marker (0 A, 1 S, 2 C) and the truth (n, 3, 3)."""
    t = np.arange(n)
    s = np.column_stack([20.0 * t, 3.0 * t, 900.0 + 25.0 * np.sin(2 * np.pi * t / 18)])
    a = s + [0.0, 200.0, 0.0]
    c = a + np.column_stack([80.0 * np.sin(t / 3.0), np.zeros(n), np.full(n, -60.0)])
    truth = np.stack([a, s, c], axis=1)
    keep = np.ones((n, 3), dtype=bool)
    keep[lost:, 0] = False
    f, m = np.nonzero(keep)
    return truth[f, m], f, m, truth


def test_links_join_each_marker_from_field_to_field() -> None:
    xyz, field, marker, _ = _walk(20)
    nxt, prv = links(xyz, field, 300.0, 20.0)
    joined = np.flatnonzero(nxt >= 0)
    assert np.all(field[nxt[joined]] == field[joined] + 1)
    assert np.all(marker[nxt[joined]] == marker[joined])
    assert np.array_equal(prv[nxt[joined]], joined)
    # every point but the last of each trajectory: A at field 9, S and C at field 19
    assert np.array_equal(np.sort(field[nxt < 0]), [9, 19, 19])


def test_a_lost_marker_is_carried_by_its_rigid_companion() -> None:
    xyz, field, marker, truth = _walk(40)
    chains = links(xyz, field, 300.0, 20.0)
    pos, at, end = carried(xyz, field, chains, 300.0, 20.0, side=1, fields=20)
    mine = (marker[end] == 0) & (field[end] == 9)
    assert np.array_equal(at[mine], np.arange(11, 30)), "2 to 20 fields on"
    # S carries A where it is (C, nearer and swinging, is not steady)
    assert np.allclose(pos[mine], truth[at[mine], 0])


def test_nothing_is_carried_without_a_steady_companion() -> None:
    xyz, field, marker, _ = _walk(40)
    swing = marker != 1  # A and C alone: C's offset to A changes by more than 20 mm
    chains = links(xyz[swing], field[swing], 300.0, 20.0)
    pos, _, _ = carried(xyz[swing], field[swing], chains, 300.0, 20.0, side=1, fields=20)
    assert len(pos) == 0
