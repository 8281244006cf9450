"""The 15-term polynomial: term order, fast evaluation, least squares, inverse, anchoring."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.grid.poly import (
    TERM_NAMES,
    Linearisation,
    anchor_affine,
    apply_linearisation,
    compose_affine,
    fit_polynomial,
    identity_linearisation,
    invert_linearisation,
    poly_terms,
)


def _lens_like(rng: np.random.Generator) -> Linearisation:
    """Identity plus a few px of smooth higher-order terms on a 752 x 291 field."""
    lin = identity_linearisation((375.5, 145.0), 376.0)
    x = lin.x + np.concatenate([[0.3, 0.002, 0.001], rng.normal(0, 2.0, 12)])
    y = lin.y + np.concatenate([[-0.2, 0.001, 0.003], rng.normal(0, 1.0, 12)])
    return Linearisation(lin.center_px, lin.scale_px, x, y)


def test_terms_follow_the_thesis_order():
    u, v = 0.7, -0.3
    expected = {
        "1": 1, "u": u, "v": v, "u^2": u * u, "uv": u * v, "v^2": v * v,
        "u^3": u**3, "u^2v": u * u * v, "uv^2": u * v * v, "v^3": v**3,
        "u^4": u**4, "u^3v": u**3 * v, "u^2v^2": u * u * v * v, "uv^3": u * v**3, "v^4": v**4,
    }  # fmt: skip
    t = poly_terms(u, v)
    assert t.shape == (15,)
    np.testing.assert_allclose(t, [expected[name] for name in TERM_NAMES], rtol=1e-15)


def test_apply_equals_the_term_matrix_product():
    rng = np.random.default_rng(3)
    lin = _lens_like(rng)
    uv = rng.uniform([0, 0], [752, 291], size=(1000, 2))
    t = poly_terms((uv[:, 0] - 375.5) / 376.0, (uv[:, 1] - 145.0) / 376.0)
    np.testing.assert_allclose(
        apply_linearisation(lin, uv), t @ np.column_stack([lin.x, lin.y]), atol=1e-9
    )
    # any leading shape
    assert apply_linearisation(lin, uv.reshape(10, 100, 2)).shape == (10, 100, 2)


def test_identity_leaves_points_unchanged():
    lin = identity_linearisation((375.5, 145.0), 376.0)
    uv = np.random.default_rng(0).uniform(-50, 800, size=(200, 2))
    np.testing.assert_allclose(apply_linearisation(lin, uv), uv, atol=1e-10)


def test_fit_recovers_a_known_polynomial():
    rng = np.random.default_rng(4)
    lin = _lens_like(rng)
    uv = rng.uniform([0, 0], [752, 291], size=(300, 2))
    fitted = fit_polynomial(uv, apply_linearisation(lin, uv), lin.center_px, lin.scale_px)
    np.testing.assert_allclose(fitted.x, lin.x, rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(fitted.y, lin.y, rtol=1e-7, atol=1e-7)


def test_fit_needs_two_dimensional_spread():
    uv = np.column_stack([np.linspace(0, 700, 50), np.full(50, 100.0)])
    with pytest.raises(KisscalError, match="span"):
        fit_polynomial(uv, uv, (350.0, 100.0), 350.0)
    with pytest.raises(KisscalError, match="at least 15"):
        fit_polynomial(uv[:10], uv[:10], (350.0, 100.0), 350.0)


def test_inverse_round_trips_over_the_whole_field():
    rng = np.random.default_rng(5)
    lin = _lens_like(rng)
    raw = rng.uniform([-5, -5], [757, 296], size=(5000, 2))
    corrected = apply_linearisation(lin, raw)
    back = invert_linearisation(lin, corrected)
    assert np.abs(back - raw).max() < 1e-8


def test_anchoring_makes_the_map_the_identity_to_first_order_at_the_centre():
    rng = np.random.default_rng(6)
    lin = _lens_like(rng)
    c = np.array([375.5, 145.0])
    anchored = compose_affine(anchor_affine(lin, c), lin)
    np.testing.assert_allclose(apply_linearisation(anchored, c), c, atol=1e-9)
    h = 1e-3
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        d = (apply_linearisation(anchored, c + e) - apply_linearisation(anchored, c - e)) / (2 * h)
        np.testing.assert_allclose(d, np.eye(2)[k], atol=1e-7)


def test_bad_coefficients_are_refused():
    with pytest.raises(KisscalError, match="15 x and 15 y"):
        Linearisation((0.0, 0.0), 1.0, np.zeros(14), np.zeros(15))
    with pytest.raises(KisscalError, match="scale_px"):
        Linearisation((0.0, 0.0), 0.0, np.zeros(15), np.zeros(15))
    with pytest.raises(KisscalError, match="shape"):
        apply_linearisation(identity_linearisation((0.0, 0.0), 1.0), np.zeros((5, 3)))
