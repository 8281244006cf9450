import numpy as np
import pytest
from numpy.typing import NDArray

from kisscal.tracking.predictors import extrapolation_weights, kalman_gains, shafiq_rule

# The tracker predicts with Shafiq's rule and looks the Kalman gains up; these are the
# plain forms of both (for many tracks at once) that the tests check them against.


def extrapolate(history: NDArray, n_points: NDArray, ahead: int = 1) -> NDArray[np.float64]:
    """Extrapolate many tracks at once with Shafiq's rule for their length.

    Parameters
    ----------
    history : (T, H, 3) array
        Last H >= 5 positions of each track, the most recent last (older slots unused).
    n_points : (T,) int array
        Number of points each track has (>= 1).
    ahead : int
        Fields past the last point.

    Returns
    -------
    (T, 3) predicted positions.
    """
    history = np.asarray(history, dtype=float)
    n_points = np.asarray(n_points)
    out = np.empty((history.shape[0], 3))
    for lo, hi in ((1, 1), (2, 2), (3, 4), (5, np.inf)):
        sel = (n_points >= lo) & (n_points <= hi)
        if not sel.any():
            continue
        used, degree = shafiq_rule(lo)
        w = extrapolation_weights(used, degree, ahead)
        out[sel] = np.einsum("k,tkc->tc", w, history[sel, -used:])
    return out


def kalman_predict(
    state: NDArray, cov: NDArray, pnc: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A-priori state and covariance: x' = A x, P' = A P A^T + Q (thesis eqs. 2.24, 3.14).

    ``state`` is (T, 3, 2) = (position, velocity) per axis; ``cov`` is (T, 2, 2).
    """
    new_state = np.empty_like(state)
    new_state[..., 0] = state[..., 0] + state[..., 1]
    new_state[..., 1] = state[..., 1]
    p00, p01, p11 = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    new_cov = np.empty_like(cov)
    new_cov[:, 0, 0] = p00 + 2 * p01 + p11 + pnc
    new_cov[:, 0, 1] = new_cov[:, 1, 0] = p01 + p11
    new_cov[:, 1, 1] = p11 + pnc
    return new_state, new_cov


def kalman_correct(
    state: NDArray, cov: NDArray, measured: NDArray, mnc: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A-posteriori state and covariance from position measurements (thesis eqs. 2.30-2.33).

    ``measured`` is (T, 3); K = P' H^T / (H P' H^T + R), x = x' + K (z - H x'),
    P = (I - K H) P'.
    """
    gain = cov[:, :, 0] / (cov[:, 0, 0] + mnc)[:, None]  # (T, 2)
    innovation = measured - state[..., 0]  # (T, 3)
    new_state = state + gain[:, None, :] * innovation[:, :, None]
    new_cov = cov - gain[:, :, None] * cov[:, None, 0, :]
    return new_state, new_cov


def test_two_point_rule_is_thesis_eq_3_11():
    np.testing.assert_allclose(extrapolation_weights(2, 1), [-1.0, 2.0], atol=1e-12)


def test_three_point_least_squares_line():
    # LSQ line through x1, x2, x3 at t = -2, -1, 0, evaluated at t = 1.
    np.testing.assert_allclose(extrapolation_weights(3, 1), [-2 / 3, 1 / 3, 4 / 3], atol=1e-12)


@pytest.mark.parametrize("ahead", [1, 2, 3])
def test_five_point_parabola_is_exact_on_parabolas(ahead):
    t = np.arange(5.0)
    x = 3.0 - 2.0 * t + 0.7 * t**2
    tn = 4.0 + ahead
    assert extrapolation_weights(5, 2, ahead) @ x == pytest.approx(3 - 2 * tn + 0.7 * tn**2)


def test_extrapolate_uses_shafiq_rule_per_track_length():
    t = np.arange(5.0)
    quad = np.stack([t**2, 0 * t, 0 * t], axis=1)
    history = np.stack([quad, quad, quad, quad])
    pred = extrapolate(history, np.array([1, 2, 3, 5]))
    assert pred[0, 0] == pytest.approx(16.0)  # one point: stays
    assert pred[1, 0] == pytest.approx(16 + 7)  # two points: linear
    assert pred[2, 0] == pytest.approx(np.polyval(np.polyfit([2, 3, 4], [4, 9, 16], 1), 5))
    assert pred[3, 0] == pytest.approx(25.0)  # parabola is exact


def test_kalman_matches_a_plain_matrix_implementation():
    rng = np.random.default_rng(3)
    a = np.array([[1.0, 1.0], [0.0, 1.0]])
    h = np.array([[1.0, 0.0]])
    q, r = 0.05 * np.eye(2), 0.1
    x = np.array([[0.0, 2.0], [5.0, -1.0], [1.0, 0.5]])  # three axes, (pos, vel)
    p = np.eye(2)
    state = x[None].copy()
    cov = p[None].copy()
    for _ in range(20):
        z = rng.normal(0, 3, 3)
        xs = x @ a.T
        ps = a @ p @ a.T + q
        k = ps @ h.T / (h @ ps @ h.T + r)
        x = xs + (z[:, None] - xs[:, :1]) * k.T
        p = (np.eye(2) - k @ h) @ ps
        state, cov = kalman_predict(state, cov, 0.05)
        state, cov = kalman_correct(state, cov, z[None], 0.1)
        np.testing.assert_allclose(state[0], x, atol=1e-10)
        np.testing.assert_allclose(cov[0], p, atol=1e-12)


@pytest.mark.parametrize(("pnc", "mnc"), [(0.5, 0.025), (0.05, 0.05), (0.005, 0.1)])
def test_gain_table_is_bit_for_bit_the_covariance_updates(pnc, mnc):
    # The tracker looks gains up by filter age: they must be the very numbers the 2 x 2
    # covariance updates give, not merely close.
    state, cov = np.zeros((1, 3, 2)), 1.5 * np.eye(2)[None]
    gains = kalman_gains(1.5, pnc, mnc, 200)
    for age in range(200):
        state, cov = kalman_predict(state, cov, pnc)
        expected = cov[0, :, 0] / (cov[0, 0, 0] + mnc)
        assert np.array_equal(gains[age], expected)
        state, cov = kalman_correct(state, cov, np.zeros((1, 3)), mnc)
