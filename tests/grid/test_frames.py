"""Frames to dots: averaging, and detection of a rendered grid (needs kisscal.detect)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.grid import average_frames, dots_from_frames, linearise_dots
from tests.grid.grid_synth import make_grid_view


def render_dots(uv: np.ndarray, size_px=(752, 291), sigma_px=(1.6, 0.85), peak=200.0):
    """Grey image of Gaussian spots (pixel centres at integer coordinates)."""
    w, h = size_px
    img = np.zeros((h, w))
    ru, rv = int(4 * sigma_px[0]) + 1, int(4 * sigma_px[1]) + 1
    du = np.arange(-ru, ru + 1)
    dv = np.arange(-rv, rv + 1)
    for u, v in uv:
        cu, cv = int(np.rint(u)), int(np.rint(v))
        us, vs = cu + du, cv + dv
        gu = np.exp(-0.5 * ((us - u) / sigma_px[0]) ** 2)
        gv = np.exp(-0.5 * ((vs - v) / sigma_px[1]) ** 2)
        ok_u, ok_v = (us >= 0) & (us < w), (vs >= 0) & (vs < h)
        img[np.ix_(vs[ok_v], us[ok_u])] += peak * np.outer(gv[ok_v], gu[ok_u])
    return img


def test_average_frames_is_the_mean_and_checks_shapes():
    frames = [np.full((4, 5), k, dtype=np.uint8) for k in (10, 20, 60)]
    np.testing.assert_allclose(average_frames(frames), np.full((4, 5), 30.0))
    with pytest.raises(KisscalError, match="no grid frames"):
        average_frames([])
    with pytest.raises(KisscalError, match="frame 1 has shape"):
        average_frames([np.zeros((4, 5)), np.zeros((4, 6))])
    with pytest.raises(KisscalError, match="2-D"):
        average_frames([np.zeros((4, 5, 3))])


def test_rendered_grid_frames_give_every_dot():
    """Dots about 7 x 3 px: detection's long/wide split would halve some (off for grids)."""
    view = make_grid_view(seed=41, noise_px=0.0, pitch_over_z=0.043)  # all inside
    clean = render_dots(view.distorted_uv) + 12.0
    rng = np.random.default_rng(41)
    frames = [
        np.clip(clean + rng.normal(0, 4.0, clean.shape), 0, 255).round().astype(np.uint8)
        for _ in range(5)
    ]
    dots = dots_from_frames(frames)
    fit = linearise_dots(dots, size_px=(752, 291))
    assert fit.index.n_indexed == 300
    # each detected dot matches its true centroid (detection accuracy, not the grid's)
    idx = fit.index
    true = {(r, c): uv for r, c, uv in zip(view.row, view.col, view.distorted_uv, strict=True)}
    ok = np.flatnonzero(idx.indexed)
    err = np.array([dots[i] - true[(idx.row[i], idx.col[i])] for i in ok])
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.08
    assert fit.linearisation.quality.residual_rms_after_px < 0.08


def test_16_bit_grid_frames_give_the_dots_of_the_8_bit_ones():
    """A threshold means the same for averaged 16-bit grid frames as for one 16-bit frame
    (detection brings 16-bit grey levels to its own scale; averaging must not skip that)."""
    view = make_grid_view(seed=41, noise_px=0.0, pitch_over_z=0.043)
    clean = render_dots(view.distorted_uv) + 12.0
    frames8 = [np.clip(clean, 0, 255).round().astype(np.uint8)] * 2
    frames16 = [f.astype(np.uint16) * 257 for f in frames8]
    dots8, dots16 = dots_from_frames(frames8), dots_from_frames(frames16)
    assert len(dots8) == len(dots16) == 300
    np.testing.assert_allclose(dots16, dots8, atol=1e-3)
