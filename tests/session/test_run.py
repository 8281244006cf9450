"""`kisscal run` end to end on a synthetic session: outputs, truth, caching, C3D."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kisscal import session
from kisscal.io.files import read_table
from kisscal.tracking.tracks import STATUS_NAMES

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def processed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Seed 5, six cameras, a 120-field gait trial, processed by `kisscal run`."""
    root = tmp_path_factory.mktemp("run") / "s5"
    session.synthesise(root, seed=5, fields=120, walking5=False)
    log: list[str] = []
    session.run(root, echo=log.append)
    (root / "run.log").write_text("\n".join(log))
    return root


def test_outputs_follow_the_design(processed: Path) -> None:
    out = processed / "out"
    for cam in range(1, 7):
        lin = json.loads((out / "linearisation" / f"cam{cam}.json").read_text())
        assert lin["model"] == "poly4" and len(lin["x"]) == 15 and len(lin["y"]) == 15
        dlt = json.loads((out / "dlt" / f"cam{cam}.json").read_text())
        chosen = dlt["lens_models"]["chosen"]  # the model held-out rods chose (issue 25)
        assert len(dlt["L"]) == 11 and dlt["method"] == ("dlt" if chosen == "dlt" else "refined")
    assert len((out / "dlt" / "dltdv.csv").read_text().strip().splitlines()) >= 11
    for trial in ("walk01", "stick", "throw"):
        tdir = out / "trials" / trial
        pts = read_table(
            tdir / "points3d.csv", required=("field", "x_mm", "y_mm", "z_mm", "n_cameras", "rms_px")
        )
        assert len(pts["field"]) > 0
        tr = read_table(
            tdir / "trajectories.csv",
            required=("field", "track", "label", "x_mm", "y_mm", "z_mm", "status"),
        )
        assert set(tr["status"]) <= set(STATUS_NAMES)
        assert (tdir / "trajectories.c3d").is_file() and (tdir / "trajectories.trc").is_file()
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["cameras"]) == {f"cam{i}" for i in range(1, 7)}
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 6  # grid x6 at least, rig, residuals, epipolar


def test_calibration_and_3d_accuracy_against_truth(processed: Path) -> None:
    truth = json.loads((processed / "truth" / "cameras.json").read_text())["cameras"]
    for cam in truth:
        dlt = json.loads((processed / "out" / "dlt" / f"{cam['id']}.json").read_text())
        assert dlt["rms_px"] < 0.08
        assert np.linalg.norm(np.subtract(dlt["centre_mm"], cam["centre_mm"])) < 10.0
    score = session.evaluate(processed)
    stick = score["stick"]["stick_length"]
    assert stick["mean_abs_error_mm"] < 1.1 and stick["sd_mm"] < 1.5  # seed 003: 1.1 / 1.5 mm
    assert score["throw"]["gravity"]["relative_error"] < 0.005
    walk = score["walk01"]
    assert walk["rmse_measured_mm"] < 1.0
    assert walk["identity_switches"] == 0


def test_gait_trajectories_are_labelled(processed: Path) -> None:
    walk = session.evaluate(processed)["walk01"]
    assert walk["n_trajectories"] == walk["n_true_markers"] == 15
    assert walk["correctly_labelled"] == 15
    assert walk["coverage"] > 0.99


@pytest.mark.filterwarnings("ignore:No analog data")
def test_c3d_matches_csv(processed: Path) -> None:
    import c3d

    tdir = processed / "out" / "trials" / "stick"
    tr = read_table(tdir / "trajectories.csv")
    with open(tdir / "trajectories.c3d", "rb") as fh:
        reader = c3d.Reader(fh)
        labels = [s.strip() for s in reader.point_labels]
        frames = [points.copy() for _, points, _ in reader.read_frames()]
        rate = reader.point_rate
    assert rate == pytest.approx(50.0)
    first = int(tr["field"].min())
    for k, label in enumerate(labels):
        rows = tr["label"] == label
        for f, x, y, z in zip(
            tr["field"][rows], tr["x_mm"][rows], tr["y_mm"][rows], tr["z_mm"][rows], strict=True
        ):
            assert frames[int(f) - first][k, :3] == pytest.approx([x, y, z], abs=1e-3)


def test_rerun_after_a_tracking_change_reuses_detection(processed: Path, tmp_path: Path) -> None:
    """Issue 6: only tracking is redone; detection, linearisation, calibration and
    reconstruction come from the cache (the session is copied: keys are relative)."""
    root = tmp_path / "copy"
    shutil.copytree(processed, root)
    log: list[str] = []
    session.run(root, overrides=session.Overrides(tracking={"pnc": 0.05}), echo=log.append)
    assert not [line for line in log if "frames in" in line]  # no fresh detection
    assert any("calibrate: cached" in line for line in log)
    assert all("cached" in line for line in log if "reconstruct " in line)
    assert sum("track " in line for line in log) == 3
    changed = [line for line in log if "linearise" in line and "cached" not in line]
    assert not changed


def kisscal(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args], capture_output=True, text=True, timeout=600
    )


def test_check_gate(processed: Path) -> None:
    ok = kisscal(
        "check",
        str(processed),
        "--max-reproj-px",
        "0.08",
        "--max-grid-px",
        "0.08",
        "--max-3d-mm",
        "1.0",
    )
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad = kisscal("check", str(processed), "--max-reproj-px", "0.001")
    assert bad.returncode == 1
    failed = [line for line in bad.stderr.splitlines() if line.startswith("FAILED")]
    assert any("dlt rms_px" in line and "cam1" in line for line in failed), bad.stderr
    assert "FAILED check: " in bad.stderr and "limits.json" in bad.stderr and bad.stdout == ""


def test_current_rig_gives_the_written_calibration(processed: Path) -> None:
    from kisscal.io.dltfiles import read_dlt_json
    from kisscal.session import current_rig

    rig = current_rig(processed)
    for cam in rig:
        written = read_dlt_json(processed / "out" / "dlt" / f"{cam.id}.json")
        assert np.array_equal(cam.dlt, written.L)
        assert cam.linearisation is not None and cam.size_px is not None


def test_single_camera_fill_reads_the_unused_blobs_in_the_rigs_pixels(processed: Path) -> None:
    """The track stage's unused blobs (points2d.csv, raw pixels) are linearised the way
    reconstruction linearised them: the used ones, taken the same way, land on the
    projections of their 3D points."""
    from kisscal.io.points2d import read_points2d
    from kisscal.io.points3d import read_points3d
    from kisscal.io.store import SessionStore
    from kisscal.session.calibrated import current_rig
    from kisscal.session.inputs import load_config
    from kisscal.session.track import _spare_blobs

    files = SessionStore(processed).trial("walk01")
    rig = current_rig(processed)
    obs = read_points2d(files.points2d)
    pts = read_points3d(files.points3d)
    used = obs.point >= 0
    cam = np.array([rig.index(c) for c in obs.camera[used]])
    uv = np.zeros((cam.size, 2))
    for i, camera in enumerate(rig):
        uv[cam == i] = camera.undistort_px(obs.xy_px[used][cam == i])
    miss = np.linalg.norm(rig.project_rows(cam, pts.xyz_mm[obs.point[used]]) - uv, axis=1)
    assert np.median(miss) < 0.5
    spare = _spare_blobs(load_config(processed), "walk01")
    # every blob, each with its point: the unused ones free, the used ones held
    assert spare is not None and spare.field.size == obs.field.size
    assert np.array_equal(np.sort(spare.field[spare.free]), np.sort(obs.field[~used]))
    assert np.array_equal(spare.free, spare.point < 0)
    summary = json.loads(files.tracking.read_text())
    assert all("single_camera_fields" in g for g in summary["fills"])


def test_current_linearisations_are_read_without_a_pool(
    processed: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A processed session's linearisations are current: the later stages' every
    ``current_rig`` (a dozen a run) reads them in its own process, starting no pool,
    and gets the written ones."""
    import kisscal.detect.sequence as sequence
    from kisscal.io.linearisation import read_linearisation
    from kisscal.session import current_rig

    def no_pool(*args: object, **kwargs: object) -> None:
        raise AssertionError("a worker pool was started to read current linearisations")

    monkeypatch.setattr(sequence, "worker_pool", no_pool)
    rig = current_rig(processed)
    for cam in rig:
        written = read_linearisation(processed / "out" / "linearisation" / f"{cam.id}.json")[1]
        assert np.array_equal(cam.linearisation.x, written.x)
        assert np.array_equal(cam.linearisation.y, written.y)


def test_export_fits_side_by_side_equal_those_in_one_process(processed: Path) -> None:
    """The exports' OpenCV fits done in worker processes are the fits done here, to the
    bit (two cameras: each fit is a second of Levenberg-Marquardt)."""
    from kisscal.session.calibrated import current_rig, read_dlt_files
    from kisscal.session.exports import _opencv_fits, fit_volume
    from kisscal.session.inputs import load_config

    cams = list(current_rig(processed))[:2]
    config = load_config(processed)
    dlts = read_dlt_files(processed, config)
    volume = fit_volume(config, dlts)
    here = _opencv_fits(cams, volume, dlts, workers=1)
    beside = _opencv_fits(cams, volume, dlts, workers=2)
    assert list(here) == list(beside) == [c.id for c in cams]
    for cam in here:
        assert here[cam].rms_px == beside[cam].rms_px
        assert np.array_equal(here[cam].camera.lens, beside[cam].camera.lens)
        assert np.array_equal(here[cam].camera.K, beside[cam].camera.K)


def test_trial_blobs_detected_ahead_are_those_detected_here(processed: Path) -> None:
    """`kisscal run` detected the trial's images in the background while it calibrated
    (its log says so, where there are two cores); the blobs it cached are, frame by frame,
    those one process detects (two cameras)."""
    import os

    from kisscal.detect import detect_jobs
    from kisscal.io.store import SessionStore
    from kisscal.session.ahead import image_job
    from kisscal.session.inputs import load_config
    from kisscal.session.params import stage_params
    from kisscal.session.runner import markers_detection, trial_stem
    from kisscal.session.trials import trial_frames_of

    config = load_config(processed)
    trial = config.trials[0]
    frames = trial_frames_of(config, trial)
    if (os.cpu_count() or 1) >= 2:
        n = sum(len(seq) for seq in frames.values())
        line = f"detect {trial.name}: {len(frames)} cameras, {n} frames, detected in the background"
        assert line in (processed / "run.log").read_text()
    detection = markers_detection(config, stage_params(config), workers=1)
    sizes = {c.id: c.size_px for c in config.cameras}
    store = SessionStore(processed)
    for cam, seq in list(frames.items())[:2]:
        job = image_job(seq, cam, sizes[cam], detection[cam], 1)
        ((_, here),) = detect_jobs([job], workers=1)
        cached = store.blobs(trial_stem(trial), cam)
        assert len(here) == len(cached) == len(seq)
        for a, b in zip(here, cached, strict=True):
            assert np.array_equal(a.x_px, b.x_px) and np.array_equal(a.y_px, b.y_px)
            assert np.array_equal(a.valid, b.valid)
