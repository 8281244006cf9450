"""Predictors: Shafiq's extrapolators and the constant-velocity Kalman filter, vectorised.

Shafiq, Tümer & Güler 2001 §4.3 predict the next position of a track from its last points:
two points by linear extrapolation, three points by a least-squares line, five points by a
least-squares parabola. Küçük 2005 §3.3.9 uses three independent constant-velocity Kalman
filters per track, one per lab axis, with state (position, velocity), ``A = [[1, 1], [0, 1]]``
(eq. 3.14) and ``H = [1, 0]`` (eq. 3.15). Because Q, R and H are the same for the three
axes, one 2 x 2 covariance per track serves all three filters.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray


@lru_cache(maxsize=64)
def extrapolation_weights(n_points: int, degree: int, ahead: int = 1) -> NDArray[np.float64]:
    """Weights ``w`` such that ``w @ last_points`` is the least-squares polynomial
    extrapolation ``ahead`` fields past the last of ``n_points`` equally spaced points.

    ``(2, 1)`` is the two-point linear rule ``2 x_i - x_{i-1}`` (thesis eq. 3.11),
    ``(3, 1)`` Shafiq's three-point least-squares line, ``(5, 2)`` the five-point parabola.
    Applied to a piece's first points in reverse order, the same weights extrapolate
    backwards in time (blending checks continuity from both sides).
    """
    t = np.arange(n_points, dtype=float) - (n_points - 1)
    vander = np.vander(t, degree + 1, increasing=True)
    target = np.float64(ahead) ** np.arange(degree + 1)
    w = target @ np.linalg.pinv(vander)
    w.setflags(write=False)
    return w


def shafiq_rule(n_points: int) -> tuple[int, int]:
    """(points used, polynomial degree) of Shafiq's extrapolator for a track of n points."""
    if n_points >= 5:
        return 5, 2
    if n_points >= 3:
        return 3, 1
    if n_points == 2:
        return 2, 1
    return 1, 0


def kalman_gains(initial_error: float, pnc: float, mnc: float, n_ages: int) -> NDArray[np.float64]:
    """Gain (position, velocity) of a filter's correction at each age 0..n_ages-1.

    Q, R and H are the same for every filter and a filter corrects on every field (with
    its prediction when the point is missing, §3.3.9), so its covariance, and hence its
    gain, depends only on how many fields it has run since it started with
    ``initial_error * I``. A tracker may then look the gain up instead of carrying a 2 x 2
    covariance per track. The arithmetic is that of the covariance's prediction (thesis
    eqs. 2.24, 3.14) followed by its correction (eqs. 2.30-2.33), term by term in the same
    order, so the gains are the same numbers to the last bit. Returns (n_ages, 2).
    """
    gains = np.empty((max(n_ages, 0), 2))
    p00, p01, p11 = float(initial_error), 0.0, float(initial_error)
    for age in range(n_ages):
        a00 = p00 + 2 * p01 + p11 + pnc
        a01 = p01 + p11
        a11 = p11 + pnc
        g0, g1 = a00 / (a00 + mnc), a01 / (a00 + mnc)
        gains[age] = g0, g1
        after = (a00 - g0 * a00, a01 - g0 * a01, a11 - g1 * a01)
        if after == (p00, p01, p11):
            # A fixed point (typically within a few dozen fields): every later age alike.
            gains[age + 1 :] = g0, g1
            break
        p00, p01, p11 = after
    return gains
