"""Calibration exports (cameras.toml, dltdv.csv) against their readers' conventions, and the
import routes ([calibration] cameras / dlt) against the session they came from.

The original session is the small synthetic one, calibrated from its grid and rods; its
trial is the true 2D centroids of the walk (no detection, so only the calibration
differs between the sessions compared).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import tomli_w
from scipy.spatial import cKDTree

from kisscal import session
from kisscal.errors import KisscalError
from kisscal.io.config import load_toml
from kisscal.io.files import read_table, write_table
from kisscal.rig import Rig
from kisscal.session.calibrated import current_rig

pytestmark = pytest.mark.slow


def centroid_trial(root: Path, trial: str = "walk01") -> None:
    """Replace the session's trials by one read from the true centroids of ``trial``."""
    truth = read_table(root / "truth" / "trials" / trial / "centroids.csv")
    config = load_toml(root / "session.toml")
    for cam in [c["id"] for c in config["cameras"]]:
        rows = truth["camera"] == cam
        write_table(
            root / "centroids" / f"{cam}.csv",
            {
                "field": truth["field"][rows].astype(int),
                "x_px": truth["u_px"][rows],
                "y_px": truth["v_px"][rows],
            },
        )
    config["trials"] = [{"name": "c2d", "centroids": "centroids/{camera}.csv"}]
    (root / "session.toml").write_text(tomli_w.dumps(config))


def points3d(root: Path) -> tuple[np.ndarray, np.ndarray]:
    t = read_table(root / "out" / "trials" / "c2d" / "points3d.csv")
    return t["field"].astype(int), np.column_stack([t["x_mm"], t["y_mm"], t["z_mm"]])


def distances_mm(a: tuple, b: tuple) -> np.ndarray:
    """Per point of ``a``: distance to the nearest point of ``b`` in the same field."""
    (fa, xa), (fb, xb) = a, b
    return np.concatenate(
        [cKDTree(xb[fb == f]).query(xa[fa == f])[0] for f in np.unique(fa) if (fb == f).any()]
    )


@pytest.fixture(scope="module")
def original(small_session: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("interop") / "orig"
    shutil.copytree(small_session, root, ignore=shutil.ignore_patterns("out"))
    centroid_trial(root)
    # refined, without L12..L16: DLTdv8 has no lens terms, so only then is its dltdv.csv
    # the whole camera (the default may choose them on this rig)
    session.calibrate(root, workers=1, refine=True)
    session.reconstruct(root, "c2d")
    return root


def imported(
    original: Path, dest: Path, calibration: dict, files: dict[str, Path], grid: bool = False
) -> Path:
    """A copy of the original session calibrated by ``calibration`` (its ``files`` copied
    in) instead of rods, with or without the grid; its trial reconstructed."""
    shutil.copytree(
        original, dest, ignore=shutil.ignore_patterns("out", "rods", "trials", "truth", "grid")
    )
    for name, src in files.items():
        shutil.copy(src, dest / name)
    config = load_toml(dest / "session.toml")
    del config["rods"]
    if grid:
        shutil.copytree(original / "grid", dest / "grid")
    else:
        del config["grid"]
    config["calibration"] = calibration
    (dest / "session.toml").write_text(tomli_w.dumps(config))
    session.calibrate(dest)
    session.reconstruct(dest, "c2d")
    return dest


def lab_points_in_view(rig: Rig, n: int = 4000) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.uniform([-1200, -700, 0], [1200, 700, 2000], (n, 3))


def test_cv2_project_points_with_cameras_toml_lands_on_kisscal_projection(original: Path):
    rig = current_rig(original)
    doc = load_toml(original / "out" / "cameras.toml")
    xyz = lab_points_in_view(rig)
    for cam in rig:
        c = doc[cam.id]
        assert c["name"] == cam.id and c["size"] == list(cam.size_px)
        uv, _ = cv2.projectPoints(
            xyz.reshape(-1, 1, 3),
            np.array(c["rotation"]),
            np.array(c["translation"]),
            np.array(c["matrix"]),
            np.array(c["distortions"]),
        )
        mine = cam.project(xyz)
        w, h = cam.size_px
        inside = (mine[:, 0] > -0.5) & (mine[:, 0] < w - 0.5)
        inside &= (mine[:, 1] > -0.5) & (mine[:, 1] < h - 0.5)
        d = np.hypot(*(uv.reshape(-1, 2) - mine)[inside].T)
        assert inside.sum() > 500
        assert np.sqrt(np.mean(d**2)) < 0.05, cam.id
        assert doc["metadata"]["fit_rms_px"][cam.id] < 0.05
        u0, v0, u1, v1 = doc["metadata"]["fit_region_px"][cam.id]  # the volume's extent
        assert -0.5 <= u0 < u1 <= w - 0.5 and -0.5 <= v0 < v1 <= h - 0.5


def test_dltdv_csv_in_dltdv8_pixels_matches_linearised_projection(original: Path):
    rig = current_rig(original)
    coefs = np.loadtxt(original / "out" / "dlt" / "dltdv.csv", delimiter=",")
    assert coefs.shape == (11, len(rig))
    xyz = lab_points_in_view(rig, 500)
    for i, cam in enumerate(rig):
        c = coefs[:, i]
        den = xyz @ c[8:11] + 1  # DLTdv8's dlt_inverse, first pixel's centre at (1, 1)
        uv8 = np.column_stack([xyz @ c[0:3] + c[3], xyz @ c[4:7] + c[7]]) / den[:, None]
        np.testing.assert_allclose(uv8 - 1, cam.project_ideal(xyz), atol=1e-6)
    exports = (original / "out" / "exports.json").read_text()
    assert "DLTdv8" in exports and "corners_px" in exports


def test_cameras_toml_import_reconstructs_the_same_points(original: Path, tmp_path: Path):
    toml = original / "out" / "cameras.toml"
    root = imported(original, tmp_path / "c", {"cameras": "cameras.toml"}, {"cameras.toml": toml})
    d = distances_mm(points3d(original), points3d(root))
    # OpenCV's 5 coefficients follow the grid polynomial to ~0.005 px rms: ~0.015 mm here
    assert np.median(d) < 0.03 and d.max() < 0.1
    lin = (root / "out" / "linearisation" / "cam1.json").read_text()
    assert '"model": "poly4"' in lin and '"fit_rms_px"' in lin
    assert '"method": "cameras"' in (root / "out" / "dlt" / "cam1.json").read_text()


def test_dltdv_import_reconstructs_the_same_points_with_the_grid(original: Path, tmp_path: Path):
    coefs = {"coefs.csv": original / "out" / "dlt" / "dltdv.csv"}
    root = imported(original, tmp_path / "d", {"dlt": "coefs.csv"}, coefs, grid=True)
    d = distances_mm(points3d(original), points3d(root))
    assert d.max() < 1e-3
    assert '"method": "dltdv"' in (root / "out" / "dlt" / "cam1.json").read_text()


def test_export_command_writes_each_format(original: Path, tmp_path: Path):
    from kisscal.cli import main

    for to, dest, *units in (
        ("anipose", "c.toml"),
        ("dltdv8", "c.csv"),
        ("opencv", "ocv"),
        ("pose2sim", "p2s.toml"),
        ("opencv", "ocv_m", "--units", "m"),
    ):
        with pytest.raises(SystemExit) as done:
            main(["export", str(original), "--to", to, "--out", str(tmp_path / dest), *units])
        assert done.value.code in (0, None)
    assert load_toml(tmp_path / "p2s.toml")["metadata"]["cameras"]["cam_02"] == "cam2"
    tvec = {}
    for folder in ("ocv", "ocv_m"):
        fs = cv2.FileStorage(str(tmp_path / folder / "cam2.yml"), cv2.FILE_STORAGE_READ)
        tvec[folder] = (fs.getNode("tvec").mat(), fs.getNode("units").string())
        fs.release()
    assert (tvec["ocv"][1], tvec["ocv_m"][1]) == ("mm", "m")
    np.testing.assert_allclose(tvec["ocv_m"][0] * 1000, tvec["ocv"][0])
    assert load_toml(tmp_path / "c.toml")["cam1"]["name"] == "cam1"
    np.testing.assert_allclose(
        np.loadtxt(tmp_path / "c.csv", delimiter=","),
        np.loadtxt(original / "out" / "dlt" / "dltdv.csv", delimiter=","),
    )
    fs = cv2.FileStorage(str(tmp_path / "ocv" / "cam2.yml"), cv2.FILE_STORAGE_READ)
    matrix = fs.getNode("camera_matrix").mat()
    np.testing.assert_allclose(matrix, load_toml(tmp_path / "c.toml")["cam2"]["matrix"])


def test_points2d_holds_the_observations_each_point_was_triangulated_from(original: Path):
    """points2d.csv: raw pixels of every observation and the points3d.csv row it went into;
    kisscal's own triangulation of each point's rows gives that row back."""
    from kisscal.io.points2d import read_points2d
    from kisscal.io.points3d import read_points3d

    trial = original / "out" / "trials" / "c2d"
    p2, p3 = read_points2d(trial / "points2d.csv"), read_points3d(trial / "points3d.csv")
    rig = current_rig(original)
    used = p2.point >= 0
    assert used.mean() > 0.9 and np.all(p2.field[used] == p3.field[p2.point[used]])
    np.testing.assert_array_equal(
        np.bincount(p2.point[used], minlength=len(p3.field)), p3.n_cameras
    )
    cam = np.array([rig.index(c) for c in p2.camera[used]])
    uv = np.zeros((used.sum(), 2))
    for c, camera in enumerate(rig):
        uv[cam == c] = camera.undistort_px(p2.xy_px[used][cam == c])
    tri = rig.triangulate(cam, uv, p2.point[used])
    np.testing.assert_allclose(tri.xyz_mm, p3.xyz_mm, atol=1e-3)  # points3d.csv: 4 decimals


def pose2sim_triangulate(
    calib: dict, names: list[str], dense_px: np.ndarray, likelihood: np.ndarray | None = None
) -> np.ndarray:
    """Pose2Sim's conventions (Pose2Sim.common.computeP, retrieve_calib_params,
    weighted_triangulation; Pose2Sim.triangulation with undistort_points): the camera
    tables in file order; raw pixels undistorted by cv2.undistortPoints onto the
    optimal new camera matrix (alpha 1) of each camera, P = optim_K [R | T] with T in
    metres, the point the last right singular vector of the stacked DLT rows. Returns
    metres. ``dense_px`` is (camera, point, 2) in ``names``' order, NaN where unused;
    ``likelihood`` (camera, point) multiplies each camera's rows (default 1)."""
    rows = np.zeros((dense_px.shape[1], 2 * len(names), 4))
    if likelihood is None:
        likelihood = np.ones(dense_px.shape[:2])
    for c, name in enumerate(names):
        cam = calib[name]
        K, dist, size = (np.array(cam[k], float) for k in ("matrix", "distortions", "size"))
        optim_K = cv2.getOptimalNewCameraMatrix(K, dist, size.astype(int), 1, size.astype(int))[0]
        R = cv2.Rodrigues(np.array(cam["rotation"], float))[0]
        P = optim_K @ np.c_[R, np.array(cam["translation"], float)]
        seen = np.isfinite(dense_px[c, :, 0])
        xy = cv2.undistortPoints(dense_px[c, seen].reshape(-1, 1, 2), K, dist, None, optim_K)
        x, y = xy.reshape(-1, 2).T
        w = likelihood[c, seen][:, None]
        rows[seen, 2 * c] = (P[0] - x[:, None] * P[2]) * w
        rows[seen, 2 * c + 1] = (P[1] - y[:, None] * P[2]) * w
    q = np.linalg.svd(rows)[2][:, -1]
    return q[:, :3] / q[:, 3:]


def test_pose2sim_export_triangulates_points2d_onto_points3d(original: Path, tmp_path: Path):
    from kisscal.io.points2d import read_points2d
    from kisscal.io.points3d import read_points3d
    from kisscal.session.exports import export

    (path,) = export(original, "pose2sim", tmp_path / "calibration" / "Calib_kisscal.toml")
    calib = load_toml(path)
    names = [k for k, v in calib.items() if isinstance(v, dict) and k != "metadata"]
    assert names == ["cam_01", "cam_02", "cam_03", "cam_04", "cam_05", "cam_06"]
    assert all(len(calib[n]["distortions"]) == 4 and not calib[n]["fisheye"] for n in names)
    assert calib["metadata"]["units"] == "m" and calib["metadata"]["adjusted"] is False
    ids = [calib["metadata"]["cameras"][n] for n in names]
    # mm: the same camera centres (the DLT's) as cameras.toml's, / 1000; the rotations are
    # fitted anew with Pose2Sim's four coefficients, so translations alone may differ
    anipose = load_toml(original / "out" / "cameras.toml")

    def centre(table: dict) -> np.ndarray:
        R = cv2.Rodrigues(np.array(table["rotation"], float))[0]
        return -R.T @ np.array(table["translation"], float)

    for n, cid in zip(names, ids, strict=True):
        np.testing.assert_allclose(centre(calib[n]) * 1000, centre(anipose[cid]), atol=0.05)
    trial = original / "out" / "trials" / "c2d"
    p2, p3 = read_points2d(trial / "points2d.csv"), read_points3d(trial / "points3d.csv")
    dense = np.full((len(ids), len(p3.field), 2), np.nan)
    weight = np.full((len(ids), len(p3.field)), np.nan)
    used = p2.point >= 0
    cam = [ids.index(c) for c in p2.camera[used]]
    dense[cam, p2.point[used]] = p2.xy_px[used]
    weight[cam, p2.point[used]] = p2.weight[used]
    d = np.linalg.norm(pose2sim_triangulate(calib, names, dense) * 1000 - p3.xyz_mm, axis=1)
    assert len(d) > 300 and np.median(d) < 0.03 and d.max() < 0.1, (np.median(d), d.max())
    # points2d's weight column is 1 / depth (m) of the point in the camera; as Pose2Sim's
    # likelihoods it makes the DLT rows pixel distances, kisscal's error: closer still
    rig = current_rig(original)
    for c in rig:
        rows = np.flatnonzero(used & (p2.camera == c.id))
        depth_m = c.depth_mm(p3.xyz_mm[p2.point[rows]]) / 1000
        np.testing.assert_allclose(p2.weight[rows], 1 / depth_m, rtol=1e-4)
    dw = pose2sim_triangulate(calib, names, dense, weight) * 1000 - p3.xyz_mm
    dw = np.linalg.norm(dw, axis=1)
    assert np.percentile(dw, 99) < np.percentile(d, 99) and dw.max() < 0.1, dw.max()


def test_pose2sim_names_map_onto_session_cameras_on_import(original: Path, tmp_path: Path):
    from kisscal.session.exports import export

    (p2s,) = export(original, "pose2sim", tmp_path / "Calib.toml")
    names = {f"cam_{i:02d}": f"cam{i}" for i in range(1, 7)}
    root = imported(
        original, tmp_path / "p", {"cameras": "Calib.toml", "names": names}, {"Calib.toml": p2s}
    )
    d = distances_mm(points3d(original), points3d(root))
    assert np.median(d) < 0.03 and d.max() < 0.1
    # without the map: one line naming the file's cameras and the way through
    config = load_toml(root / "session.toml")
    del config["calibration"]["names"]
    (root / "session.toml").write_text(tomli_w.dumps(config))
    with pytest.raises(KisscalError, match=r"no camera named 'cam1' .*cam_01.*names = "):
        session.calibrate(root)


def test_export_units(original: Path, tmp_path: Path):
    from kisscal.session.exports import export

    (mm,) = export(original, "anipose", tmp_path / "mm.toml")
    (m,) = export(original, "anipose", tmp_path / "m.toml", units="m")
    a, b = load_toml(mm), load_toml(m)
    assert b["metadata"]["units"] == "m"
    np.testing.assert_allclose(np.array(b["cam3"]["translation"]) * 1000, a["cam3"]["translation"])
    with pytest.raises(KisscalError, match="Pose2Sim reads metres only"):
        export(original, "pose2sim", tmp_path / "x.toml", units="mm")
    with pytest.raises(KisscalError, match="--units applies to anipose and opencv"):
        export(original, "dltdv8", tmp_path / "x.csv", units="m")
