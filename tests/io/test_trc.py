"""trajectories.trc against OpenSim's reader: its own TRCFileAdapter when the ``opensim``
package is installed (Python >= 3.11), and always against a re-implementation of its
tokenizer rules (OpenSim/Common/FileAdapter.cpp ``tokenize``, TRCFileAdapter.cpp
``extendRead``), so that the rules are checked on every Python version."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.io.export import TRC_AXES, write_trc
from kisscal.tracking.tracks import FILLED, MEASURED, Tracks, make_tracks

RATE_HZ = 100.0


def gappy_tracks(n_fields: int = 30, n_tracks: int = 4, seed: int = 0) -> Tracks:
    """Tracks whose last marker has gaps (also at the first and last field)."""
    rng = np.random.default_rng(seed)
    field = np.tile(np.arange(n_fields), n_tracks)
    track = np.repeat(np.arange(n_tracks), n_fields)
    xyz = rng.normal(0, 500, (len(field), 3))
    keep = np.ones(len(field), bool)
    last = track == n_tracks - 1
    keep[last & ((field % 4 == 1) | (field == 0) | (field == n_fields - 1))] = False
    keep[(track == 0) & (field == 7)] = False
    status = np.where(field % 5 == 0, FILLED, MEASURED)
    rows = np.flatnonzero(keep)
    # measured samples come from input points numbered in row order
    point = np.full(len(field), -1)
    point[rows] = np.where(status[rows] == MEASURED, np.arange(len(rows)), -1)
    return make_tracks(field[rows], track[rows], xyz[rows], xyz[rows], status[rows], point[rows])


def opensim_tokenize(line: str, delims: str) -> list[str]:
    """FileAdapter::tokenize: split at every delimiter, trim each token, and keep the text
    after the last delimiter only when it is not empty."""
    tokens, start = [], 0
    for i, ch in enumerate(line):
        if ch in delims:
            tokens.append(line[start:i].strip())
            start = i + 1
    if len(line) > start:
        tokens.append(line[start:].strip())
    return tokens


def opensim_read_trc(text: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """TRCFileAdapter::extendRead, the checks that decide whether a file loads."""
    lines = text.split("\n")
    head = opensim_tokenize(lines[0], " \t\r")
    assert head[0] == "PathFileType"
    keys = [k for k in opensim_tokenize(lines[1], "\t\r") if k]
    values = [v for v in opensim_tokenize(lines[2], "\t\r") if v]
    assert keys[:3] == ["DataRate", "CameraRate", "NumFrames"] and len(keys) == 8
    assert len(values) == len(keys)
    meta = dict(zip(keys, values, strict=True))
    n_markers = int(meta["NumMarkers"])
    labels = [c for c in opensim_tokenize(lines[3], "\t\r") if c]
    assert len(labels) == n_markers + 2 and labels[:2] == ["Frame#", "Time"]
    xyz = [c for c in opensim_tokenize(lines[4], "\t\r") if c]
    assert xyz == [f"{a}{i}" for i in range(1, n_markers + 1) for a in "XYZ"]
    k = 5
    while not opensim_tokenize(lines[k], "\t\r") or not opensim_tokenize(lines[k], "\t\r")[0]:
        k += 1
    times, data = [], []
    for line in lines[k:]:
        row = opensim_tokenize(line, "\t\r")
        if not row:
            break  # an empty line ends the data
        if len(row) != 3 * n_markers + 2:
            raise ValueError(
                f"Unexpected number of columns in line {k + 1}. "
                f"Expected = {3 * n_markers + 2}. Received = {len(row)}"
            )
        cells = np.array([float(c) if c else np.nan for c in row[2:]]).reshape(-1, 3)
        cells[np.isnan(cells).any(axis=1)] = np.nan
        times.append(float(row[1]))
        data.append(cells)
        k += 1
    assert len(data) == int(meta["NumFrames"])
    return labels[2:], np.array(times), np.array(data)


@pytest.mark.parametrize("up", ["z", "y"])
def test_every_frame_and_marker_read_by_opensim_rules(tmp_path, up):
    tracks = gappy_tracks()
    labels = ("RASI", "LASI", "RKNE", "RTOE")
    path = write_trc(tmp_path / "t.trc", tracks, labels, RATE_HZ, up=up)
    names, times, data = opensim_read_trc(path.read_text())
    assert names == list(labels)
    expected = tracks.positions() @ TRC_AXES[up].T  # (markers, fields, 3)
    np.testing.assert_allclose(times, np.arange(expected.shape[1]) / RATE_HZ, atol=1e-5)
    np.testing.assert_allclose(np.transpose(data, (1, 0, 2)), expected, atol=5e-4)
    assert np.isnan(data[:, -1]).any()  # the last marker's gaps came back as gaps


def test_trc_y_up_is_a_rotation_with_lab_z_as_y():
    R = TRC_AXES["y"]
    np.testing.assert_allclose(R @ R.T, np.eye(3))
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ [0, 0, 1.0], [0, 1.0, 0])  # lab up is TRC Y
    np.testing.assert_allclose(R @ [1.0, 0, 0], [1.0, 0, 0])  # walkway stays X


def test_trc_refuses_an_unknown_up_axis(tmp_path):
    with pytest.raises(KisscalError, match="up axis"):
        write_trc(tmp_path / "t.trc", gappy_tracks(), ("A", "B", "C", "D"), RATE_HZ, up="x")


def test_opensim_trc_file_adapter_loads_gaps_in_the_last_marker(tmp_path):
    osim = pytest.importorskip("opensim")  # wheels for Python >= 3.11 (test extra)
    tracks = gappy_tracks()
    labels = ("RASI", "LASI", "RKNE", "RTOE")
    path = write_trc(tmp_path / "t.trc", tracks, labels, RATE_HZ, up="y")
    # TimeSeriesTableVec3(file) reads through the TRCFileAdapter registered for ".trc"
    table = osim.TimeSeriesTableVec3(str(path))
    expected = tracks.positions() @ TRC_AXES["y"].T
    assert table.getNumRows() == expected.shape[1]
    assert list(table.getColumnLabels()) == list(labels)
    got = np.array(
        [
            [[table.getRowAtIndex(r)[c][i] for i in range(3)] for c in range(len(labels))]
            for r in range(table.getNumRows())
        ]
    )
    np.testing.assert_allclose(np.transpose(got, (1, 0, 2)), expected, atol=5e-4)
    times = np.array(table.getIndependentColumn())
    np.testing.assert_allclose(times, np.arange(expected.shape[1]) / RATE_HZ, atol=1e-5)
