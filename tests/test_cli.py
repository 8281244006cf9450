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
