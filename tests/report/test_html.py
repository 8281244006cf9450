"""The report page: status first, every camera and trial, no dump, offline, small."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from kisscal.report.html import build_report
from kisscal.report.params import ReportParams
from tests.report._session import CAMERAS, write_session

TRIALS = ("walk", "stick", "throw", "broken")


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A session reported once (its own figures drawn once, kept in out/figures/)."""
    root = write_session(tmp_path_factory.mktemp("report") / "s").root
    build_report(root)
    return root


@pytest.fixture()
def session(built: Path, tmp_path: Path) -> Path:
    """A copy of the built session for a test to change."""
    return Path(shutil.copytree(built, tmp_path / "s"))


@pytest.fixture(scope="module")
def page(built: Path) -> str:
    return (built / "out" / "report.html").read_text()


def _page(root: Path, params: ReportParams | None = None) -> str:
    return build_report(root, params).read_text()


def _section(page: str, id_: str) -> str:
    start = page.index(f'<section id="{id_}"')
    return page[start : page.index("</section>", start)]


def _status_rows(page: str) -> dict[str, str]:
    """Status table rows: check name -> the row's badge state."""
    status = _section(page, "status")
    rows = re.findall(r'<span class="badge (\w+)">[^<]*</span></td><td>([^<]+)</td>', status)
    return {name: state for state, name in rows}


def test_status_block_comes_first_with_a_line_per_camera_and_trial(page: str) -> None:
    body = page[page.index("<body>") :]
    sections = re.findall(r'<section id="(\w+)"', body)
    assert sections[0] == "status"
    assert sections.index("calibration") < sections.index("trials") < sections.index("viewer")
    rows = _status_rows(page)
    assert set(CAMERAS) | set(TRIALS) | {"3D error"} <= set(rows)
    assert all(rows[c] == "pass" for c in CAMERAS)
    assert rows["broken"] == "fail" and rows["stick"] == "pass" and rows["throw"] == "pass"
    assert "file not found" in _section(page, "status")


def test_every_camera_and_trial_has_a_row_in_its_table(page: str) -> None:
    calibration, trials = _section(page, "calibration"), _section(page, "trials")
    for cam in CAMERAS:
        assert f"<td><b>{cam}</b></td>" in calibration
    for trial in TRIALS:
        assert f"<td><b>{trial}</b></td>" in trials
    # camera centres rounded to the millimetre
    assert ">-2528</td>" in calibration and "4045</td>" in calibration


def test_no_key_value_dump_and_truth_only_at_the_end(page: str) -> None:
    assert not re.search(r"\d+ items", page)
    text = re.sub(r"<script.*?</script>|src=\"data:[^\"]+\"", "", page, flags=re.S)
    assert not re.search(r"\d\.\d{6,}", text)  # no 16-decimal numbers
    assert "truth." not in text
    body = page[page.index("<body>") :]
    assert re.findall(r'<section id="(\w+)"', body)[-1] == "truth"
    assert "0.326" in _section(page, "truth")


def test_offline_and_small(page: str) -> None:
    assert not re.search(r"(src|href)\s*=\s*[\"']?\s*(https?:)?//", page, flags=re.I)
    assert "http://" not in page and "https://" not in page
    assert "<link" not in page  # styles inlined
    assert len(page.encode()) < 400_000


def test_stale_and_unknown_figures(page: str) -> None:
    assert 'alt="grid cam1"' in page  # the camera's grid figure, in its section
    assert "grid_gone" not in page  # a camera no longer in the session: stale, not shown
    assert 'alt="custom_extra"' in _section(page, "figures")  # a stage the report does not know


def test_stored_check_limits_replace_the_defaults(session: Path) -> None:
    (session / "out" / "limits.json").write_text(json.dumps({"max_reproj_px": 0.0105}))
    rows = _status_rows(_page(session))
    assert rows["cam1"] == "pass" and rows["cam2"] == "fail" and rows["cam3"] == "fail"
    assert "DLT ≤ 0.0105 px" in _page(session)


def test_params_set_the_limits(session: Path) -> None:
    rows = _status_rows(_page(session, ReportParams(max_3d_mm=0.2, max_grid_px=0.02)))
    assert rows["3D error"] == "fail"
    assert rows["cam1"] == "pass" and rows["cam2"] == "fail"


def test_missing_marker_warns(session: Path) -> None:
    path = session / "out" / "summary.json"
    summary = json.loads(path.read_text())
    summary["trials"]["walk"]["tracking"]["missing"] = ["C"]
    path.write_text(json.dumps(summary))
    page = _page(session)
    assert _status_rows(page)["walk"] == "warn"
    assert "missing C" in _section(page, "status")


def test_future_sections_appear_only_with_their_data(session: Path) -> None:
    page = _page(session)
    for id_ in ("detection", "wand", "gait"):
        assert f'<section id="{id_}"' not in page
    out = session / "out"
    (out / "detection").mkdir()
    settings = {
        "threshold": {"value": 131.0, "source": "given", "why": "from [detection]"},
        "pixel_aspect": {"value": 1.94, "source": "derived", "why": "the grid's dot lattice"},
    }
    doc = {"markers": {"marker_pixels": [12, 47], "noise_sigma": 1.5, "settings": settings}}
    (out / "detection" / "cam2.json").write_text(json.dumps({"camera": "cam2", "kinds": doc}))
    (out / "dlt" / "wand.json").parent.mkdir(exist_ok=True)
    (out / "dlt" / "wand.json").write_text(
        json.dumps(
            {
                "length_mean_mm": 500.02,
                "length_sd_mm": 0.41,
                "cameras": {"cam1": {"rms_px": 0.21, "points": 1200}},
                "rods_weighed": "rods_route",
                "rods_weight_fits": {
                    "own_noise_leave_one_rod_out_mm": 0.0662,
                    "rods_route_leave_one_rod_out_mm": 0.0613,
                },
            }
        )
    )
    (out / "trials" / "walk" / "events.csv").write_text(
        "side,event,field,time_s\nleft,foot_strike,12,0.24\nright,foot_off,30,0.6\n"
    )
    (out / "trials" / "walk" / "spatiotemporal.csv").write_text(
        "parameter,value,sd\ncadence_steps_min,112.5,2.1\n"
    )
    page = _page(session)
    detection = _section(page, "detection")
    assert "131" in detection and "cam2" in detection and "12–47" in detection
    assert "1.940" in detection and "threshold" in detection
    wand = _section(page, "wand")
    assert "length SD (mm)" in wand and "1 200" in wand and "0.210" in wand
    # which of the rods' two weights was kept, and both fits' leave-one-rod-out (issue 25)
    assert "Rods weighed as the rods route does" in wand and "0.061" in wand
    gait = _section(page, "gait")
    assert "foot_strike" in gait and "cadence_steps_min" in gait and "112.500" in gait
    cams = _section(page, "trials")
    assert "2 cameras" in cams and "3 cameras" in cams and "0 cameras" not in cams


def test_viewer_data_is_valid_json_with_every_trajectory(session: Path) -> None:
    page = _page(session, ReportParams(viewer_samples=150, stick_length_mm=502.5))
    raw = re.search(r'<script type="application/json" id="kc-data">(.*?)</script>', page, re.S)
    data = json.loads(raw.group(1).replace("<\\/", "</"))
    names = [t["name"] for t in data["trials"]]
    assert names == ["walk", "stick", "throw"]  # the failed trial has no trajectories
    walk = data["trials"][0]
    assert walk["labels"] == ["A", "B", "C"] and walk["segments"] == [[0, 1], [1, 2]]
    assert len(walk["labels"]) * walk["frames"] <= 150
    assert walk["rate"] == pytest.approx(50.0 / walk["step"])
    assert data["trials"][1]["segments"] == [[0, 1]]  # the stick's two markers are joined
    assert [c["id"] for c in data["cameras"]] == list(CAMERAS)


def test_report_without_session_toml_still_names_cameras_and_trials(session: Path) -> None:
    (session / "session.toml").unlink()
    page = _page(session)
    rows = _status_rows(page)
    assert set(CAMERAS) <= set(rows) and "walk" in rows
    assert "session.toml not read" in page


def test_without_summary_the_figures_are_read_from_the_stage_outputs(session: Path) -> None:
    out = session / "out"
    (out / "summary.json").unlink()
    (out / "dlt").mkdir()
    doc = {
        "camera": "cam2",
        "L": [0.0] * 11,
        "method": "mdlt",
        "rms_px": 0.0421,
        "centre_mm": [10.4, 20.6, 3000.2],
        "n_points": 24,
    }
    (out / "dlt" / "cam2.json").write_text(json.dumps(doc))
    page = _page(session)
    rows = _status_rows(page)
    assert rows["cam2"] == "pass" and rows["cam1"] == "fail"  # cam1 was never calibrated
    calibration = _section(page, "calibration")
    assert "mdlt" in calibration and "0.042" in calibration and ">3000</td>" in calibration


def _status_text(page: str, name: str) -> str:
    """The text of a trial's status row."""
    status = _section(page, "status")
    start = status.index(f"<td>{name}</td>")
    return re.sub(r"<[^>]+>", " ", status[start : status.index("</tr>", start)])


def test_the_stick_is_checked_only_when_its_length_is_given(session: Path) -> None:
    given = _status_text(_page(session), "stick")
    assert "true 502.5 mm" in given
    toml = session / "session.toml"
    toml.write_text(toml.read_text().replace("stick_length_mm = 502.5", ""))
    unset = _page(session, ReportParams())
    assert "mean |error|" not in _status_text(unset, "stick")
    assert "true 502.5 mm" not in unset


def test_an_empty_trial_is_processed_not_pending(session: Path) -> None:
    path = session / "out" / "trials" / "walk" / "trajectories.csv"
    path.write_text(path.read_text().splitlines()[0] + "\n")  # the header only
    summary_path = session / "out" / "summary.json"
    summary = json.loads(summary_path.read_text())
    summary["trials"]["walk"]["reconstruction"].update(points=0, fields=100)
    summary_path.write_text(json.dumps(summary))
    page = _page(session)
    text = _status_text(page, "walk")
    assert "not processed yet" not in text and "processed, no trajectories" in text
    assert "0 3D points in its 100 fields" in text and _status_rows(page)["walk"] == "warn"
    del summary["trials"]["walk"]
    summary_path.write_text(json.dumps(summary))
    assert "not processed yet" in _status_text(_page(session), "walk")


def test_the_trajectories_of_a_trial_to_check_are_unfolded(session: Path) -> None:
    path = session / "out" / "summary.json"
    summary = json.loads(path.read_text())
    summary["trials"]["walk"]["tracking"]["missing"] = ["C"]
    path.write_text(json.dumps(summary))
    page = _page(session)
    assert _status_rows(page)["walk"] == "warn" and _status_rows(page)["stick"] == "pass"
    opened = re.findall(r"<details open=\"\w+\"><summary>(\w+): every trajectory", page)
    folded = re.findall(r"<details><summary>(\w+): every trajectory", page)
    assert opened == ["walk"] and "stick" in folded


def test_the_camera_models_compared_are_one_table(session: Path) -> None:
    """Each camera's ``lens_models`` (issue 25) becomes a row; the chosen model is named,
    the rig's held-out 3D error is the last row."""
    out = session / "out"
    (out / "dlt").mkdir(exist_ok=True)
    for i, cam in enumerate(CAMERAS):
        models = {
            m: {
                "model": m,
                "held_out_3d_rms_mm": 0.2 + 0.1 * k,
                "held_out_rms_px": 0.01 * (k + 1) + 0.001 * i,
                "in_sample_rms_px": 0.005,
            }
            for k, m in enumerate(("dlt", "refined", "lens"))
        }
        doc = {"camera": cam, "L": [0.0] * 11, "method": "dlt", "rms_px": 0.01}
        doc["lens_models"] = {"chosen": "dlt", "by": "held-out 3D error", "folds": 4}
        doc["lens_models"]["models"] = models
        (out / "dlt" / f"{cam}.json").write_text(json.dumps(doc))
    calibration = _section(_page(session), "calibration")
    assert "Camera model chosen by held-out 3D error" in calibration
    for i in range(len(CAMERAS)):
        assert f"{0.01 + 0.001 * i:.4f}" in calibration
    assert "rig, 3D (mm)" in calibration and "0.4000" in calibration
