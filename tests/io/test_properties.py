"""Property tests of the readers and writers: no traceback on any text, exact round trips.

The example budget comes from the Hypothesis profile (tests/conftest.py): ``ci`` by
default, ``thorough`` (10x) with ``HYPOTHESIS_PROFILE=thorough``.
"""

from __future__ import annotations

import string
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from kisscal.detect import Blobs
from kisscal.errors import KisscalError
from kisscal.io.blobs import write_blobs
from kisscal.io.config import load_toml, parse_session
from kisscal.io.files import read_table, write_table
from tests.io.blob_csv import read_blobs

KEYS = ["session", "cameras", "grid", "rods", "trials", "markers", "wand", "axes", "detection"]
SCALARS = st.one_of(
    st.integers(-5, 5000), st.floats(allow_nan=True), st.text(max_size=12), st.booleans()
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(
            st.sampled_from(KEYS + ["id", "name", "images", "size", "rate_hz"]), inner, max_size=4
        )
    ),
    max_leaves=12,
)


@given(st.dictionaries(st.sampled_from(KEYS), VALUES, max_size=6))
def test_session_parser_only_raises_kisscal_errors(data: dict) -> None:
    try:
        parse_session(data, Path("/lab"))
    except KisscalError as exc:
        assert "\n" not in str(exc)


@given(st.text(alphabet=string.printable + "äé\ufeff", max_size=300))
def test_toml_reader_only_raises_kisscal_errors(text: str) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "session.toml"
        path.write_text(text, encoding="utf-8")
        try:
            parse_session(load_toml(path), Path(folder))
        except KisscalError:
            pass


@given(st.text(alphabet=string.printable, max_size=300))
def test_table_reader_only_raises_kisscal_errors(text: str) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.csv"
        path.write_text(text, encoding="utf-8")
        try:
            read_table(path, required=("field", "x_px"), numeric=("field", "x_px"))
        except KisscalError:
            pass


FINITE = st.floats(-1e6, 1e6, allow_nan=False, width=64)


@given(
    st.integers(0, 40).flatmap(
        lambda n: st.tuples(
            st.lists(FINITE, min_size=n, max_size=n),
            st.lists(st.integers(-9, 9999), min_size=n, max_size=n),
        )
    )
)
def test_tables_read_back(columns: tuple[list[float], list[int]]) -> None:
    x, field = columns
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.csv"
        write_table(path, {"field": np.array(field, int), "x_mm": np.array(x, float)})
        back = read_table(path, required=("field", "x_mm"))
    assert np.array_equal(back["field"], np.array(field, float))
    assert np.allclose(back["x_mm"], x, rtol=1e-6, atol=1e-6)


@given(
    st.lists(
        st.tuples(
            st.floats(0, 2000, allow_nan=False),
            st.floats(0, 2000, allow_nan=False),
            st.integers(1, 500),
            st.booleans(),
            st.integers(0, 255),
        ),
        max_size=30,
    )
)
def test_blob_tables_read_back(rows: list[tuple[float, float, int, bool, int]]) -> None:
    n = len(rows)
    cols = list(zip(*rows, strict=True)) if rows else [[]] * 5
    blobs = Blobs(
        x_px=np.array(cols[0], float),
        y_px=np.array(cols[1], float),
        x_binary_px=np.array(cols[0], float),
        y_binary_px=np.array(cols[1], float),
        pixels=np.array(cols[2], int),
        w_px=np.full(n, 3),
        h_px=np.full(n, 2),
        valid=np.array(cols[3], bool),
        flags=np.array(cols[4], int) & 0,
    )
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "blobs.csv"
        write_blobs(path, [("frames/a.png", blobs)])
        back = read_blobs(path).get("frames/a.png")
    if n == 0:
        assert back is None or len(back) == 0
        return
    assert back is not None
    assert np.allclose(back.x_px, blobs.x_px, atol=1e-4) and np.allclose(
        back.y_px, blobs.y_px, atol=1e-4
    )
    assert np.array_equal(back.valid, blobs.valid) and np.array_equal(back.pixels, blobs.pixels)
