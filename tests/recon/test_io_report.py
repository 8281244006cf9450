"""points3d.csv round trip and the epipolar figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.errors import KisscalError
from kisscal.io.points3d import blob_index_in_field, read_points3d, write_trial_points
from kisscal.recon import ReconParams, match_field, reconstruct_trial
from kisscal.recon.epipolar import epipolar_lines, fundamental_from_dlt
from kisscal.report.epipolar import clip_lines, epipolar_figure, trial_field_figure

from .rig import make_rig, make_table, random_markers


def test_blob_index_in_field_counts_within_field_and_camera() -> None:
    field = np.array([1, 0, 1, 0, 1, 0])
    camera = np.array([0, 0, 0, 1, 1, 0])
    assert blob_index_in_field(field, camera).tolist() == [0, 0, 1, 0, 0, 1]


def test_points3d_round_trip_names_the_blobs(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    dlts = make_rig(0)
    xyz = random_markers(rng, 5, 6)
    field, camera, uv, _, _ = make_table(rng, dlts, xyz)
    pts = reconstruct_trial(field, camera, uv, dlts, ReconParams(stationary_filter=False))
    ids = [f"cam{k + 1}" for k in range(6)]
    path = write_trial_points(tmp_path / "t" / "points3d.csv", pts, field, camera, ids)
    assert path.read_text().splitlines()[0].startswith("field,x_mm,y_mm,z_mm,n_cameras,rms_px")
    back = read_points3d(path)
    assert back.camera_ids == tuple(ids)
    assert np.array_equal(back.field, pts.field)
    assert np.allclose(back.xyz_mm, pts.xyz_mm, atol=1e-4)
    assert np.array_equal(back.n_cameras, (back.blob >= 0).sum(axis=1))
    # the named blob is the k-th row of that camera in that field, in input order
    index = blob_index_in_field(field, camera)
    for p in range(len(back.field)):
        for c in range(6):
            if back.blob[p, c] >= 0:
                row = np.flatnonzero(
                    (field == back.field[p]) & (camera == c) & (index == back.blob[p, c])
                )
                assert row.tolist() == [pts.blob_row[p, c]]
    with pytest.raises(KisscalError):
        read_points3d(tmp_path / "missing.csv")


def test_clip_lines_end_on_the_line_and_the_image_border() -> None:
    dlts = make_rig(1)
    F = fundamental_from_dlt(dlts[0], dlts[2])
    xyz = random_markers(np.random.default_rng(1), 1, 10)[0]
    lines = epipolar_lines(F, project(dlts[0], xyz))
    ends = clip_lines(lines, 752, 291)
    for k in range(2):
        assert np.allclose(np.einsum("ij,ij->i", lines[:, :2], ends[:, k]) + lines[:, 2], 0)
    on_border = np.isclose(ends[..., 0], -0.5) | np.isclose(ends[..., 0], 751.5)
    on_border |= np.isclose(ends[..., 1], -0.5) | np.isclose(ends[..., 1], 290.5)
    assert on_border.all()


def test_epipolar_figure_has_one_panel_per_camera_with_all_lines() -> None:
    dlts = make_rig(2)
    xyz = random_markers(np.random.default_rng(2), 1, 5)[0]
    points = [project(L, xyz) for L in dlts]
    matches = match_field(points, dlts)
    fig = epipolar_figure(points, dlts, (752, 291), matches, title="field 0")
    axes = fig.get_axes()
    assert len(axes) == 6
    for ax in axes:
        assert len(ax.collections[0].get_segments()) == 5 * 5
    with pytest.raises(KisscalError):
        epipolar_figure(points[:3], dlts, (752, 291))


def test_trial_field_figure_colours_the_reconstructed_markers(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    dlts = make_rig(3)
    xyz = random_markers(rng, 30, 6)
    field, camera, uv, _, _ = make_table(rng, dlts, xyz, n_leds=1)
    pts = reconstruct_trial(field, camera, uv, dlts)
    fig = trial_field_figure(pts, 4, field, camera, uv, dlts, (752, 291))
    assert fig.texts[0].get_text().startswith(f"field 4: {int((pts.field == 4).sum())} markers")
    fig.savefig(tmp_path / "epi.png")
    assert (tmp_path / "epi.png").stat().st_size > 10_000


def test_summary_counts_every_blob_once() -> None:
    rng = np.random.default_rng(4)
    dlts = make_rig(4)
    xyz = random_markers(rng, 20, 8)
    field, camera, uv, _, _ = make_table(rng, dlts, xyz, n_leds=1, n_noise=1)
    # the "LEDs" are fixed spots anywhere (reflections): judge them by motion, short as
    # the trial is
    pts = reconstruct_trial(field, camera, uv, dlts, ReconParams(stationary_min_s=0.0))
    s = pts.summary()
    assert s["blobs"] == len(field)
    assert s["blobs_used"] + s["blobs_stationary"] + s["blobs_unmatched"] == len(field)
    assert s["blobs_used"] == int(pts.n_cameras.sum())
    assert sum(s["points_by_n_cameras"]) == s["points"] == len(pts)
    assert s["blobs_stationary"] >= 6 * 20  # one LED per camera in every field
    assert s["rms_px_max"] <= ReconParams().max_rms_px
    with pytest.raises(KisscalError):
        reconstruct_trial(field, camera, uv, np.where(np.arange(11) == 3, np.nan, dlts))


def test_poor_coverage_is_a_warning_with_its_numbers() -> None:
    rng = np.random.default_rng(6)
    dlts = make_rig(6)
    xyz = random_markers(rng, 30, 10)
    field, camera, uv, _, _ = make_table(rng, dlts, xyz)
    full = reconstruct_trial(field, camera, uv, dlts).summary(30)
    assert full["warnings"] == [] and full["coverage"] > 0.95
    assert full["markers_per_field"] == 10 and full["fields"] == 30
    # cameras 2-5 lose every blob of the second half of the trial: half of it has no points
    late = (field >= 15) & (camera >= 2)
    half = reconstruct_trial(field[~late], camera[~late], uv[~late], dlts).summary(30)
    (line,) = [w for w in half["warnings"] if w.startswith("coverage")]
    assert f"{half['points']} points in 30 fields of up to 10 markers" in line
    assert half["coverage"] < 0.6
    (line,) = [w for w in half["warnings"] if "unmatched" in w]
    assert f"({half['blobs_unmatched']} of {half['blobs'] - half['blobs_stationary']};" in line
