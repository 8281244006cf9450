"""points2d.csv: written and read back exactly; malformed files are one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.io.points2d import COLUMNS, observation_points, read_points2d, write_points2d


def test_round_trip_keeps_ids_pixels_and_unused_rows(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    n = 500
    camera = rng.integers(0, 3, n)
    field = np.sort(rng.integers(0, 50, n))
    xy = rng.uniform(-0.5, 1023.5, (n, 2))
    point = np.where(rng.random(n) < 0.2, -1, rng.integers(0, 200, n))
    weight = np.where(point >= 0, rng.uniform(0.1, 2.0, n), np.nan)
    path = write_points2d(
        tmp_path / "p.csv", ("01", "02", "cam 3"), camera, field, xy, point, weight
    )
    assert path.read_text().splitlines()[0] == ",".join(COLUMNS)
    back = read_points2d(path)
    assert back.camera.tolist() == [("01", "02", "cam 3")[c] for c in camera]  # text ids stay
    np.testing.assert_array_equal(back.field, field)
    np.testing.assert_array_equal(back.point, point)
    np.testing.assert_allclose(back.xy_px, xy, atol=5e-7)  # six decimals
    np.testing.assert_allclose(back.weight, weight, rtol=1e-8)  # nine significant digits
    assert np.array_equal(np.isnan(back.weight), point < 0)
    unused = path.read_text().splitlines()[1 + int(np.argmax(point < 0))]
    assert unused.endswith(",,")  # an unused observation has an empty point and weight


def test_files_without_the_weight_column_read_with_nan_weights(tmp_path: Path) -> None:
    (tmp_path / "p.csv").write_text("camera,field,x_px,y_px,point\nc1,0,1.5,2.5,0\nc2,0,3,4,\n")
    back = read_points2d(tmp_path / "p.csv")
    np.testing.assert_array_equal(back.point, [0, -1])
    assert back.weight.shape == (2,) and np.isnan(back.weight).all()


def test_empty_trial(tmp_path: Path) -> None:
    path = write_points2d(tmp_path / "p.csv", ("c1",), [], [], np.zeros((0, 2)), [])
    assert len(read_points2d(path).field) == 0


def test_observation_points_inverts_the_rows_of_each_point() -> None:
    blob_row = np.array([[4, -1, 0], [1, 2, -1], [-1, -1, 3]])
    np.testing.assert_array_equal(observation_points(blob_row, 6), [0, 1, 1, 2, 0, -1])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("camera,field,x,y,point\n", "header must be"),
        ("camera,field,x_px,y_px,point\nc1,0,1.5\n", "ragged rows"),
        ("camera,field,x_px,y_px,point\nc1,zero,1.5,2.5,\n", "text in field"),
        ("camera,field,x_px,y_px,point,weight\nc1,0,1.5,2.5,0,heavy\n", "point, weight"),
    ],
)
def test_malformed_files(tmp_path: Path, text: str, message: str) -> None:
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(KisscalError, match=message):
        read_points2d(tmp_path / "p.csv")
