"""trajectories.c3d read back by two independent readers: the ``c3d`` package (which reads
the C3D standard) and ezc3d; the per-sample residual says measured / filled / gap."""

from __future__ import annotations

import warnings

import c3d
import ezc3d
import numpy as np
import pytest

from kisscal.io.c3d import C3D_MASK_CAMERAS
from kisscal.io.export import write_c3d
from kisscal.io.points3d import Points3DFile
from kisscal.tracking.tracks import MEASURED
from tests.io.test_trc import gappy_tracks

RATE_HZ = 120.0
LABELS = ("RASI", "LASI", "RKNE", "RTOE")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A C3D of tracks with gaps and filled samples, and the points3d rows behind it."""
    tracks = gappy_tracks(n_fields=40)
    rng = np.random.default_rng(4)
    n = int(tracks.point.max()) + 1
    seen = rng.random((n, 9)) < 0.5
    seen[np.arange(n), rng.integers(0, 7, n)] = True  # every point seen by a camera 1..7
    points = Points3DFile(
        field=np.zeros(n, np.int64),
        xyz_mm=np.zeros((n, 3)),
        n_cameras=seen.sum(axis=1),
        rms_px=rng.uniform(0.01, 3.0, n),
        blob=np.where(seen, 0, -1),
        camera_ids=tuple(f"cam{i}" for i in range(9)),
    )
    residual_mm = points.rms_px * 0.8  # e.g. a pixel 0.8 mm wide at the points
    path = write_c3d(
        tmp_path_factory.mktemp("c3d") / "t.c3d",
        tracks,
        LABELS,
        RATE_HZ,
        points=points,
        residual_mm=residual_mm,
    )
    return path, tracks, points


def expected(tracks, points):
    """Per (track, field): status class (1 measured, 0 filled/predicted, -1 gap), residual
    and camera mask of the measured samples."""
    n_fields = int(tracks.field.max()) + 1
    kind = np.full((tracks.n_tracks, n_fields), -1)
    rms = np.zeros_like(kind, dtype=float)
    mask = np.zeros_like(kind)
    measured = tracks.status == MEASURED
    kind[tracks.track, tracks.field] = measured.astype(int)
    row = tracks.point[measured]
    rms[tracks.track[measured], tracks.field[measured]] = points.rms_px[row] * 0.8
    bits = (points.blob[row, :C3D_MASK_CAMERAS] >= 0) * (1 << np.arange(C3D_MASK_CAMERAS))
    mask[tracks.track[measured], tracks.field[measured]] = bits.sum(axis=1)
    return kind, rms, mask


def read_with_c3d_package(path):
    with path.open("rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no analog data"
        reader = c3d.Reader(fh)
        frames = [(no, pts.copy()) for no, pts, _ in reader.read_frames()]
        meta = {
            "first": reader.first_frame,
            "rate": reader.point_rate,
            "scale": reader.point_scale,
            "labels": [s.strip() for s in reader.point_labels],
            "units": reader.get("POINT:UNITS").string_value.strip(),
            "start": reader.get("TRIAL:ACTUAL_START_FIELD").int16_array.tolist(),
            "end": reader.get("TRIAL:ACTUAL_END_FIELD").int16_array.tolist(),
        }
    return meta, frames


def test_c3d_package_reads_residual_and_camera_mask_of_every_sample(written):
    path, tracks, points = written
    kind, rms, mask = expected(tracks, points)
    meta, frames = read_with_c3d_package(path)
    n_fields = kind.shape[1]
    assert meta["labels"] == list(LABELS) and meta["units"] == "mm"
    assert meta["rate"] == pytest.approx(RATE_HZ) and meta["first"] == 1
    assert meta["start"] == [1, 0] and meta["end"] == [n_fields, 0]
    assert [no for no, _ in frames] == list(range(1, n_fields + 1))
    data = np.stack([pts for _, pts in frames], axis=1)  # (points, frames, 5)
    residual, cameras = data[..., 3], data[..., 4]
    assert np.all(residual[kind == 1] > 0)
    assert np.all(residual[kind == 0] == 0) and np.all(cameras[kind == 0] == 0)
    assert np.all(residual[kind == -1] == -1)
    scale = abs(meta["scale"])
    m = kind == 1
    np.testing.assert_allclose(residual[m], np.maximum(rms[m], scale), atol=scale / 2 + 1e-6)
    np.testing.assert_array_equal(cameras[m], mask[m])
    dense = tracks.positions()
    np.testing.assert_allclose(data[..., :3][kind >= 0], dense[kind >= 0], atol=1e-3)


def test_ezc3d_reads_the_same_samples_as_measured_filled_and_gaps(written):
    path, tracks, points = written
    kind, _, _ = expected(tracks, points)
    c = ezc3d.c3d(str(path))
    residual = c["data"]["meta_points"]["residuals"][0]  # (points, frames)
    assert np.all(residual[kind == 1] > 0)
    assert np.all(residual[kind == 0] == 0)
    assert np.all(residual[kind == -1] == -1)
    assert list(c["parameters"]["POINT"]["LABELS"]["value"]) == list(LABELS)
    assert c["parameters"]["POINT"]["RATE"]["value"][0] == pytest.approx(RATE_HZ)
    assert c["header"]["points"]["first_frame"] == 0  # ezc3d counts from 0: frame 1
    descriptions = c["parameters"]["POINT"]["DESCRIPTIONS"]["value"]
    n_measured = np.bincount(tracks.track[tracks.status == MEASURED])
    assert all(
        d.startswith(f"kisscal: {k} measured")
        for k, d in zip(n_measured, descriptions, strict=True)
    )
    xyz = c["data"]["points"][:3].transpose(1, 2, 0)
    np.testing.assert_allclose(xyz[kind >= 0], tracks.positions()[kind >= 0], atol=1e-3)
    assert np.isnan(xyz[kind == -1]).all()


def test_source_first_frame_trailing_frames_and_lab_parameters_read_back(tmp_path):
    """A C3D trial's output keeps its source's numbering (frame 153 on) and every frame
    (trailing frames without samples), and says who wrote it and which axis is up, as the
    c3d package, ezc3d and Kinetics Toolkit read it."""
    ktk = pytest.importorskip("kineticstoolkit")
    tracks = gappy_tracks(n_fields=40)
    path = write_c3d(tmp_path / "t.c3d", tracks, LABELS, RATE_HZ, n_fields=50, first_frame=153)
    meta, frames = read_with_c3d_package(path)
    assert meta["first"] == 153 and [no for no, _ in frames] == list(range(153, 203))
    assert meta["start"] == [153, 0] and meta["end"] == [202, 0]
    c = ezc3d.c3d(str(path))
    assert c["header"]["points"]["first_frame"] == 152  # ezc3d counts from 0
    assert c["data"]["points"].shape[2] == 50
    params = c["parameters"]
    assert params["MANUFACTURER"]["COMPANY"]["value"] == ["kisscal"]
    assert params["POINT"]["X_SCREEN"]["value"] == ["+X"]
    assert params["POINT"]["Y_SCREEN"]["value"] == ["+Z"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        markers = ktk.read_c3d(str(path))["Points"]
    assert len(markers.time) == 50
    assert markers.time[0] == pytest.approx(152 / RATE_HZ)  # Kinetics Toolkit: frame 1 at 0 s
    dense = tracks.positions()
    np.testing.assert_allclose(
        markers.data[LABELS[0]][:40, :3] * 1000.0, dense[0], atol=1e-3, equal_nan=True
    )


def test_every_camera_of_a_sample_is_listed_beyond_the_mask(written, tmp_path):
    from kisscal.io.export import write_sample_cameras

    _, tracks, points = written
    path = write_sample_cameras(tmp_path / "cams.csv", tracks, LABELS, points)
    rows = path.read_text().splitlines()[1:]
    measured = np.flatnonzero(tracks.status == MEASURED)
    assert len(rows) == len(measured)
    wide = [
        (r, i)
        for r, i in zip(rows, measured, strict=True)
        if (points.blob[tracks.point[i], 7:] >= 0).any()
    ]
    assert wide  # some samples were seen by cameras 8 and 9, outside the C3D mask
    for row, i in wide:
        listed = row.split(",")[2].split()
        seen = [
            c
            for c, b in zip(points.camera_ids, points.blob[tracks.point[i]], strict=True)
            if b >= 0
        ]
        assert listed == seen
