"""The CLI lists every command and turns user errors into one line with exit code 2."""

from __future__ import annotations

import subprocess
import sys

import pytest

COMMANDS = [
    "demo",
    "synth",
    "detect",
    "linearise",
    "calibrate",
    "reconstruct",
    "track",
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
