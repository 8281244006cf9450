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


def _run(session_dir: Path, **env: str) -> dict[str, bytes]:
    """``kisscal run session_dir`` in a new process with ``env`` added; its outputs."""
    result = subprocess.run(
        [sys.executable, "-m", "kisscal", "run", str(session_dir)],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, **env},
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return outputs(session_dir)


def test_spawned_workers_give_the_forked_run_s_outputs(processed: Path, tmp_path: Path) -> None:
    """The session run by ``kisscal run`` with its workers spawned gives the outputs of the
    shared run of conftest.py, whose workers were started the default way (forked on
    Linux). Both size the BLAS thread pools the same way (:mod:`kisscal.cli.blas`, which
    the tests' conftest.py imports first, as the command line does): on some machines
    (AMD EPYC, OpenBLAS of NumPy 2.4) one thread or two change the DLT's last digits
    (1e-12 relative)."""
    a = outputs(processed)
    b = _run(copy_of(processed, tmp_path / "spawned"), **{START_METHOD_ENV: "spawn"})
    assert len(a) > 20 and sorted(a) == sorted(b)
    assert [name for name in a if a[name] != b[name]] == []
