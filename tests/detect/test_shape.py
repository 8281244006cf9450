"""Spot shape from moments, corrected for growth (kisscal.detect.shape)."""

from __future__ import annotations

import numpy as np

from kisscal.detect.shape import (
    PIXEL_AREA_VAR,
    corrected_moments,
    frame_growth,
    height_ratio,
    principal_axes,
)

ASPECT = 1.94


def _moments(a: np.ndarray, growth: float, extra_x: float = 0.0, extra_y: float = 0.0):
    """Variances of round spots of x spread ``a`` grown by ``growth``, plus pair spreads."""
    sx = a + growth
    sy = a / ASPECT + growth
    return sx**2 + extra_x + PIXEL_AREA_VAR, sy**2 + extra_y + PIXEL_AREA_VAR


def test_growth_is_recovered_from_single_spots_with_a_few_pairs():
    a = np.linspace(0.8, 2.5, 20)
    vx, vy = _moments(a, 0.4)
    vx[:3] += 4.0  # three side-by-side pairs among twenty groups
    usable = np.ones(20, dtype=bool)
    sx, sy = np.sqrt(vx - PIXEL_AREA_VAR), np.sqrt(vy - PIXEL_AREA_VAR)
    one = (np.zeros(20, dtype=np.int64), 1)  # all groups in one frame
    growth = frame_growth(sx, sy, usable, one, ASPECT, fallback=0.0, min_groups=5)
    assert abs(growth[0] - 0.4) < 0.02
    # too few groups: the configured value
    assert frame_growth(sx, sy, usable & (a < 1.0), one, ASPECT, 0.35, 5)[0] == 0.35


def test_corrected_ratio_is_one_for_round_spots_of_any_size():
    a = np.linspace(0.8, 3.0, 12)
    vx, vy = _moments(a, 0.5)
    cx, cy, _ = corrected_moments(vx, vy, np.zeros_like(vx), 0.5)
    assert np.allclose(height_ratio(cx, cy, ASPECT), 1.0, atol=1e-6)
    # uncorrected, the small ones look tall (why the correction exists)
    raw = height_ratio(vx - PIXEL_AREA_VAR, vy - PIXEL_AREA_VAR, ASPECT)
    assert raw[0] > 1.3


def test_principal_axes_of_a_diagonal_pair():
    # two round spots of spread 1 (round units) one radius apart along 45 degrees
    d = 2.0  # spread 1 ~ radius 2 for a disc (variance r^2 / 4)
    u = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4)])
    cov = np.eye(2) + np.outer(u, u) * d**2 / 4
    vx = np.array([cov[0, 0] * ASPECT**2])
    vy = np.array([cov[1, 1]])
    cxy = np.array([cov[0, 1] * ASPECT])
    major, minor, ux, uy = principal_axes(vx, vy, cxy, ASPECT)
    assert np.isclose(major[0], 2.0) and np.isclose(minor[0], 1.0)
    assert np.isclose(abs(ux[0]), abs(uy[0]))
    assert np.isclose(np.sqrt(major[0] - minor[0]), d / 2)
