import warnings

import c3d
import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.io.export import write_c3d, write_trc
from kisscal.io.trajectories import (
    HEADER,
    read_trajectories_csv,
    write_sweep_csv,
    write_trajectories_csv,
)
from kisscal.tracking import STATUS_NAMES, TrackingParams, build_trajectories, sweep_noise
from tests.tracking._data import NAMES, SEGMENTS, gait_truth, observe, template


@pytest.fixture(scope="module")
def result():
    truth = gait_truth(120, 3)
    field, xyz, _, _ = observe(truth, 3, noise_mm=0.5, ghosts_per_field=0.5)
    return build_trajectories(field, xyz, TrackingParams(), NAMES, template())


def test_csv_round_trip(tmp_path, result):
    path = write_trajectories_csv(
        tmp_path / "out" / "trajectories.csv", result.tracks, result.labels
    )
    assert path.read_text().splitlines()[0] == ",".join(HEADER)
    table = read_trajectories_csv(path)
    tracks = result.tracks
    np.testing.assert_array_equal(table.field, tracks.field)
    np.testing.assert_array_equal(table.track, tracks.track)
    np.testing.assert_allclose(table.xyz_mm, tracks.xyz_mm, atol=5e-4)
    np.testing.assert_array_equal(table.status, tracks.status)
    assert table.labels() == result.labels
    assert set(np.unique(np.asarray(STATUS_NAMES)[table.status])) <= set(STATUS_NAMES)


def test_csv_reader_rejects_bad_files(tmp_path):
    bad = tmp_path / "t.csv"
    bad.write_text("field,track\n1,2\n")
    with pytest.raises(KisscalError):
        read_trajectories_csv(bad)
    bad.write_text(",".join(HEADER) + "\n0,0,A,1,2,3,guessed\n")
    with pytest.raises(KisscalError):
        read_trajectories_csv(bad)
    with pytest.raises(KisscalError):
        read_trajectories_csv(tmp_path / "missing.csv")


def test_c3d_read_back_with_independent_reader_matches_csv(tmp_path, result):
    csv_path = write_trajectories_csv(tmp_path / "t.csv", result.tracks, result.labels)
    c3d_path = write_c3d(tmp_path / "t.c3d", result.tracks, result.labels, rate_hz=50.0)
    table = read_trajectories_csv(csv_path)
    with c3d_path.open("rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no analog data" is expected
        reader = c3d.Reader(fh)
        assert reader.point_rate == pytest.approx(50.0)
        labels = [s.strip() for s in reader.point_labels]
        assert labels == list(result.labels)
        units = reader.get("POINT:UNITS").string_value.strip()
        assert units == "mm"
        frames = {}
        for frame_no, points, _ in reader.read_frames():
            frames[frame_no - reader.first_frame] = points
    n_fields = int(table.field.max()) + 1
    assert len(frames) == n_fields
    for f, t, xyz in zip(table.field, table.track, table.xyz_mm, strict=True):
        row = frames[int(f)][t]
        assert row[3] >= 0  # residual: present
        np.testing.assert_allclose(row[:3], xyz, atol=2e-3)
    # Fields where a track has no sample are missing in the C3D (residual -1).
    have = np.zeros((result.tracks.n_tracks, n_fields), dtype=bool)
    have[table.track, table.field] = True
    t, f = np.nonzero(~have)
    for ti, fi in list(zip(t, f, strict=True))[:50]:
        assert frames[int(fi)][ti][3] == -1


def test_trc_has_opensim_header_and_values(tmp_path, result):
    path = write_trc(tmp_path / "t.trc", result.tracks, result.labels, rate_hz=50.0)
    lines = path.read_text().splitlines()
    assert lines[0].split("\t")[:3] == ["PathFileType", "4", "(X/Y/Z)"]
    head = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=True))
    assert float(head["DataRate"]) == 50.0 and head["Units"] == "mm"
    n_fields = int(result.tracks.field.max()) + 1
    assert int(head["NumFrames"]) == n_fields
    assert int(head["NumMarkers"]) == result.tracks.n_tracks
    names = [c for c in lines[3].split("\t")[2:] if c]
    assert names == list(result.labels)
    rows = [line.split("\t") for line in lines[6:]]
    assert len(rows) == n_fields
    tr = result.tracks
    i = len(tr.field) // 2
    row = rows[tr.field[i]]
    assert int(row[0]) == tr.field[i] + 1
    assert float(row[1]) == pytest.approx(tr.field[i] / 50.0)
    got = [float(v) for v in row[2 + 3 * tr.track[i] : 5 + 3 * tr.track[i]]]
    np.testing.assert_allclose(got, tr.xyz_mm[i], atol=5e-4)


def test_export_refuses_duplicate_labels(tmp_path, result):
    labels = ("A",) * result.tracks.n_tracks
    with pytest.raises(KisscalError):
        write_c3d(tmp_path / "x.c3d", result.tracks, labels, 50.0)


def test_sweep_csv(tmp_path):
    truth = gait_truth(150, 8)
    field, xyz, _, _ = observe(truth, 8, noise_mm=0.5, ghosts_per_field=0.3)
    rows = sweep_noise(
        field,
        xyz,
        SEGMENTS,
        names=NAMES,
        template_mm=template(),
        pnc_values=(0.05, 0.5),
        mnc_values=(0.05,),
    )
    path = write_sweep_csv(tmp_path / "sweep.csv", rows)
    lines = path.read_text().splitlines()
    assert lines[0].startswith("pnc,mnc,segment,kind,n_fields,mean_mm")
    assert len(lines) == 1 + sum(len(r.segments) for r in rows)
    pred = (tmp_path / "sweep_predictions.csv").read_text().splitlines()
    assert pred[0] == "pnc,mnc,label,n_predicted"
    assert len(pred) == 1 + 2 * len(NAMES)


def test_a_trial_without_trajectories_gets_files_without_points(tmp_path):
    import ezc3d

    empty = build_trajectories(np.zeros(0, int), np.zeros((0, 3)), TrackingParams())
    assert empty.tracks.n_tracks == 0
    c3d_path = write_c3d(tmp_path / "t.c3d", empty.tracks, empty.labels, 50.0, n_fields=5)
    data = ezc3d.c3d(str(c3d_path))
    assert data["data"]["points"].shape == (4, 0, 5)
    assert data["parameters"]["POINT"]["RATE"]["value"][0] == 50.0
    trc = write_trc(tmp_path / "t.trc", empty.tracks, empty.labels, 50.0, n_fields=5)
    rows = trc.read_text().splitlines()
    assert rows[2].split("\t")[2:4] == ["5", "0"]  # NumFrames, NumMarkers
    assert rows[-5:] == [f"{f + 1}\t{f / 50:.5f}\t" for f in range(5)]  # tab-ended, as OpenSim
    csv_path = write_trajectories_csv(tmp_path / "t.csv", empty.tracks, empty.labels)
    assert csv_path.read_text() == ",".join(HEADER) + "\n"
    with pytest.raises(KisscalError, match="no trajectories"):
        write_c3d(tmp_path / "u.c3d", empty.tracks, empty.labels, 50.0)
