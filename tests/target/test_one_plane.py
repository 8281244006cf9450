"""Matches that stay on one level of a stepped target are told apart (a warning's cause)."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.params import DltParams
from kisscal.target.one_plane import unmatched_beside_one_plane

# a stepped target: columns 10 mm apart, every other one 10 mm higher; its image a grid
GRID = [(x, y) for x in range(0, 70, 10) for y in range(0, 50, 10)]
TARGET = np.array([[x, y, 10.0 * (x % 20 > 0)] for x, y in GRID])
DOTS = TARGET[:, :2] * 3.0 + 100.0
LOW = TARGET[:, 2] == 0


def test_the_other_levels_dots_among_one_levels_matches_are_counted() -> None:
    dot = np.where(LOW, np.arange(len(TARGET)), -1)
    assert unmatched_beside_one_plane(TARGET, DOTS, dot, DltParams()) == int((~LOW).sum())


def test_matches_on_both_levels_or_a_flat_target_say_nothing() -> None:
    every = np.arange(len(TARGET))
    assert unmatched_beside_one_plane(TARGET, DOTS, every, DltParams()) == 0
    some = np.where(LOW | (np.arange(len(TARGET)) == 7), every, -1)  # one point off it
    assert unmatched_beside_one_plane(TARGET, DOTS, some, DltParams()) == 0
    flat = TARGET * [1, 1, 0]
    low_only = np.where(LOW, every, -1)
    assert unmatched_beside_one_plane(flat, DOTS, low_only, DltParams()) == 0
