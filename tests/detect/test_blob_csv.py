"""The blob CSV of DESIGN.md (kisscal.io.blobs) and the overlay (kisscal.report.overlay)."""

from __future__ import annotations

import numpy as np

from fixtures.fig9 import fig9_params, make_fig9
from kisscal.detect import Blobs, detect_blobs
from kisscal.io.blobs import COLUMNS, write_blobs
from kisscal.report.overlay import INVALID_RGB, VALID_RGB, draw_overlay
from tests.io.blob_csv import read_blobs


def test_csv_round_trip(tmp_path):
    blobs = detect_blobs(make_fig9(), fig9_params())
    path = tmp_path / "blobs.csv"
    n = write_blobs(path, [("a/fig9.png", blobs), ("empty.png", Blobs.empty())])
    assert n == len(blobs)
    text = path.read_text().splitlines()
    assert text[0] == ",".join(COLUMNS)
    assert any("too_large" in line and line.endswith("too_large") for line in text)
    back = read_blobs(path)
    assert list(back) == ["a/fig9.png"]
    got = back["a/fig9.png"]
    assert np.allclose(got.x_px, blobs.x_px, atol=1e-4)
    for name in ("pixels", "w_px", "h_px", "valid", "flags"):
        assert np.array_equal(getattr(got, name), getattr(blobs, name))


def test_overlay_colours_valid_and_invalid():
    image = make_fig9()
    blobs = detect_blobs(image, fig9_params())
    rgb = draw_overlay(image, blobs, scale=(2, 4))
    assert rgb.shape == (image.shape[0] * 4, image.shape[1] * 2, 3)
    assert rgb.dtype == np.uint8
    colours = {tuple(c) for c in rgb.reshape(-1, 3)[::7]}
    assert VALID_RGB in colours and INVALID_RGB in colours
    # the centroid cross of each blob is drawn in its colour
    for i in range(len(blobs)):
        x = round((blobs.x_px[i] + 0.5) * 2 - 0.5)
        y = round((blobs.y_px[i] + 0.5) * 4 - 0.5)
        expected = VALID_RGB if blobs.valid[i] else INVALID_RGB
        patch = rgb[y - 1 : y + 2, x - 1 : x + 2].reshape(-1, 3)
        assert any(tuple(p) == expected for p in patch)
