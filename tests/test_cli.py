"""The CLI lists every command and turns user errors into one line with exit code 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

COMMANDS = [
    "demo",
    "synth",
    "detect",
    "init",
    "linearise",
    "calibrate",
    "reconstruct",
    "track",
    "validate",
    "run",
    "check",
    "report",
    "batch",
]


def kisscal(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args], capture_output=True, text=True, timeout=120
    )


def test_help_lists_every_command() -> None:
    result = kisscal("--help")
    assert result.returncode == 0
    for command in COMMANDS:
        assert command in result.stdout


@pytest.mark.parametrize("command", ["synth", "linearise", "calibrate", "check"])
def test_missing_argument_is_a_usage_error(command: str) -> None:
    result = kisscal(command)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    "args",
    [
        ["run", "MISSING"],
        ["linearise", "MISSING"],
        ["calibrate", "MISSING"],
        ["reconstruct", "MISSING", "walk01"],
        ["track", "MISSING", "walk01"],
        ["check", "MISSING", "--max-reproj-px", "1"],
        ["report", "MISSING"],
        ["detect", "MISSING/frame.png"],
    ],
)
def test_missing_folder_is_one_line_and_nothing_is_created(tmp_path, args: list[str]) -> None:
    missing = tmp_path / "no-such-session"
    result = kisscal(*[str(missing) if a.startswith("MISSING") else a for a in args])
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "no-such-session" in lines[0], result.stderr
    assert not missing.exists()


def test_unwritable_output_is_one_line(tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    result = kisscal("synth", str(blocker / "session"), "--fields", "10", "--cameras", "2")
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


def test_version_and_short_help() -> None:
    version = kisscal("--version")
    assert version.returncode == 0 and version.stdout.startswith("kisscal ")
    short = kisscal("calibrate", "-h")
    assert short.returncode == 0 and "Examples:" in short.stdout and "--mdlt" in short.stdout
    assert "<bool>" not in short.stdout  # flags read as flags, not as --mdlt <bool>


@pytest.mark.parametrize("command", [c for c in COMMANDS])
def test_every_command_has_an_example(command: str) -> None:
    result = kisscal(command, "--help")
    assert result.returncode == 0
    assert f"kisscal {command}" in result.stdout.split("Examples:")[-1]


def test_errors_name_the_command(tmp_path) -> None:
    result = kisscal("check", str(tmp_path))
    assert result.returncode == 2
    assert result.stderr.startswith("kisscal check: error: give at least one of")
    bad_choice = kisscal("linearise", str(tmp_path), "--model", "affine")
    assert bad_choice.returncode == 2
    assert (
        bad_choice.stderr.startswith("kisscal linearise: error:")
        and "homography" in bad_choice.stderr
    )


def test_report_of_an_unrun_session_is_an_error(small_session, tmp_path) -> None:
    import shutil

    session = tmp_path / "unrun"
    shutil.copytree(small_session, session, ignore=shutil.ignore_patterns("out"))
    result = kisscal("report", str(session))
    assert result.returncode == 2
    assert "nothing to report yet" in result.stderr
    assert not (session / "out" / "report.html").exists()


def test_detect_prints_the_table_without_out(tmp_path) -> None:
    import cv2
    import numpy as np

    image = np.zeros((60, 80), np.uint8)
    for centre in ((20, 30), (55, 20)):  # markers as a 1.94:1 field camera images them
        cv2.ellipse(image, centre, (6, 3), 0, 0, 360, 230, -1)
    cv2.imwrite(str(tmp_path / "f.png"), image)
    # two markers are too few to measure the pixel aspect from: the user gives it
    result = kisscal("detect", str(tmp_path / "f.png"), "--pixel-aspect", "1.94")
    assert result.returncode == 0
    assert "pixel aspect 1.94" in result.stderr and "given: pixel_aspect" in result.stderr
    lines = result.stdout.strip().splitlines()
    assert lines[0] == "image,x_px,y_px,pixels,w_px,h_px,valid,flags"
    xy = sorted((float(r.split(",")[1]), float(r.split(",")[2])) for r in lines[1:])
    assert np.allclose(xy, [(20, 30), (55, 20)], atol=0.15)  # cv2.ellipse is not symmetric
