"""The command line's log: stderr always, data on stdout, --quiet and --verbose."""

from __future__ import annotations

import logging
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from kisscal.cli.log import level_from_flags, level_of

ROOT = Path(__file__).resolve().parents[2]


def kisscal(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    # PYTHONPATH: from another folder, `python -m kisscal` must still run this tree's code
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        env=env,
    )


def test_levels_from_flags_anywhere_before_a_double_dash() -> None:
    assert level_from_flags(["run", "S", "--quiet"]) == (logging.WARNING, ["run", "S"])
    assert level_from_flags(["-v", "run", "S"]) == (logging.DEBUG, ["run", "S"])
    assert level_from_flags(["-q", "run", "-v", "S"])[0] == logging.DEBUG  # the last wins
    assert level_from_flags(["detect", "--", "-q"]) == (logging.INFO, ["detect", "--", "-q"])


def test_a_message_is_logged_at_the_level_its_first_word_names() -> None:
    assert level_of("  warning: walk01: 45 % of blobs unmatched") == logging.WARNING
    assert level_of("problem: trial walk01: no images") == logging.ERROR
    assert level_of("FAILED cam1: dlt rms_px 0.2 over the limit 0.1") == logging.ERROR
    assert level_of("[1/4] linearisation") == logging.INFO
    assert level_of("") == logging.INFO


def test_the_log_is_on_stderr_whatever_the_level(small_session: Path) -> None:
    normal = kisscal("validate", str(small_session))
    assert normal.returncode == 0, normal.stderr
    assert normal.stdout == "" and "every input is present" in normal.stderr
    quiet = kisscal("validate", str(small_session), "--quiet")
    assert quiet.returncode == 0 and quiet.stdout == "" and quiet.stderr == ""
    verbose = kisscal("-v", "validate", str(small_session))
    assert verbose.returncode == 0 and verbose.stdout == ""
    assert verbose.stderr.startswith("[") and " ms] " in verbose.stderr
    version = kisscal("--version", "--quiet")
    assert version.stdout.startswith("kisscal ") and version.stderr == ""


def test_a_session_is_given_as_its_folder_its_toml_or_the_current_folder(
    small_session: Path, tmp_path: Path
) -> None:
    toml = kisscal("validate", str(small_session / "session.toml"))
    assert toml.returncode == 0, toml.stderr
    assert f"{small_session}: every input is present" in toml.stderr
    here = kisscal("validate", cwd=small_session)
    assert here.returncode == 0 and "every input is present" in here.stderr
    empty = kisscal("run", cwd=tmp_path)  # no argument: this folder, which is no session
    assert empty.returncode == 2
    message = f"kisscal run: error: {tmp_path / 'session.toml'}: file not found"
    assert empty.stderr.strip() == message
    # run given a session.toml reads its folder (it once said "session folder not found")
    named = kisscal("run", str(tmp_path / "session.toml"))
    assert named.returncode == 2 and named.stderr.strip() == message


@pytest.mark.slow
def test_run_ends_with_a_verdict_line(small_session: Path, tmp_path: Path) -> None:
    root = tmp_path / "s"
    shutil.copytree(small_session, root)
    result = kisscal("run", str(root), "--verbose")
    assert result.returncode == 0, result.stderr[-2000:]
    last = result.stderr.strip().splitlines()[-1]
    assert re.match(r"\[ *\d+ ms\] kisscal run: done in \d+ s: 3 trials processed", last), last
    assert re.search(r"ms\] linearise: [\d.]+ s$", result.stderr, re.M)  # a debug line
    assert str(root / "out" / "report.html") in last
    assert "1 trajectories" not in result.stderr and "1 pieces" not in result.stderr
    # the dltdv.csv line says what the corner difference is, not an alarm ("off by")
    exports = [line for line in result.stderr.splitlines() if "dltdv.csv" in line]
    assert exports and all("the lens distortion kisscal corrects" in e for e in exports)
    assert not any("off by" in e for e in exports), exports
    assert result.stdout == ""


@pytest.mark.slow
def test_progress_bars_show_elapsed_time_and_eta(small_session: Path, tmp_path: Path) -> None:
    root = tmp_path / "s"
    shutil.copytree(small_session, root, ignore=shutil.ignore_patterns("out"))
    env = {**os.environ, "PYTHONPATH": str(ROOT), "FORCE_COLOR": "1", "COLUMNS": "160"}
    result = subprocess.run(  # FORCE_COLOR: rich draws its bars as on a terminal
        [sys.executable, "-m", "kisscal", "linearise", str(root), "--camera", "cam1"],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "ETA" in result.stderr and re.search(r"\d:\d\d:\d\d", result.stderr)
    assert "linearise cam1" in result.stderr and result.stdout == ""
