"""Windows-safe processing: a whole session run with worker processes spawned (Windows'
only start method, macOS's default) gives the outputs of the forked run, to the byte."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from kisscal._shared import START_METHOD_ENV
from tests.session.conftest import copy_of

pytestmark = pytest.mark.slow


def outputs(root: Path) -> dict[str, bytes]:
    """Every table and JSON file a run writes (summary.json holds timings: left out)."""
    out = root / "out"
    files = [*out.rglob("*.csv"), *out.rglob("*.json")]
    return {
        str(f.relative_to(out)): f.read_bytes()
        for f in files
        if "cache" not in f.parts and f.name != "summary.json"
    }


def test_spawned_workers_give_the_forked_run_s_outputs(
    synthesised: Path, processed: Path, tmp_path: Path
) -> None:
    """``processed`` is the same session run in the test process with two workers started
    the default way (forked on Linux); here ``kisscal run`` spawns its workers."""
    spawned = copy_of(synthesised, tmp_path / "spawned")
    env = {**os.environ, START_METHOD_ENV: "spawn"}
    result = subprocess.run(
        [sys.executable, "-m", "kisscal", "run", str(spawned)],
        capture_output=True,
        text=True,
        timeout=900,
        env=env,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    a, b = outputs(processed), outputs(spawned)
    assert len(a) > 20 and sorted(a) == sorted(b)
    assert [name for name in a if a[name] != b[name]] == []
