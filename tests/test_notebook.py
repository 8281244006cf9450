"""The walkthrough notebook (jupytext percent script) runs from start to end."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "walkthrough.py"


@pytest.mark.slow
def test_walkthrough_runs(tmp_path: Path) -> None:
    env = {**os.environ, "KISSCAL_WALKTHROUGH_DIR": str(tmp_path), "MPLBACKEND": "Agg"}
    result = subprocess.run(
        [sys.executable, str(NOTEBOOK)], capture_output=True, text=True, timeout=600, env=env
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert "3D points" in result.stdout and "trajectories" in result.stdout
    assert (tmp_path / "figures" / "trajectories.png").stat().st_size > 10_000
    assert (tmp_path / "session" / "out" / "report.html").is_file()
