"""``kisscal batch`` on a Dask cluster started as a lab starts one, from the command line:
a scheduler and a worker command with two (daemonic) worker processes, on loopback."""

from __future__ import annotations

import importlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kisscal.errors import KisscalError
from tests.session.conftest import copy_of

ROOT = Path(__file__).resolve().parents[2]


def dask_command(*args: str, log: Path) -> subprocess.Popen:
    """``dask ARGS`` (as ``python -m dask``: this interpreter), in its own process group,
    seeing this checkout's kisscal."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    return subprocess.Popen(
        [sys.executable, "-m", "dask", *args],
        stdout=log.open("w"),
        stderr=subprocess.STDOUT,
        env=env,
        cwd=ROOT,
        start_new_session=True,
    )


def stop(process: subprocess.Popen) -> None:
    """End a command started here and everything it started (its process group)."""
    if process.poll() is None:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(20)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(20)


def scheduler_address(scheduler_file: Path, deadline: float) -> str:
    while time.monotonic() < deadline:
        if scheduler_file.is_file():
            try:
                return json.loads(scheduler_file.read_text())["address"]
            except (ValueError, KeyError):
                pass  # being written
        time.sleep(0.2)
    raise TimeoutError("the Dask scheduler did not start")


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "killpg"), reason="process groups: POSIX")
def test_batch_on_a_scheduler_and_two_worker_processes(synthesised: Path, tmp_path: Path) -> None:
    # two copies of the shared session, each with its throw trial alone: every stage from
    # the grid to the report runs in a daemonic worker process, on the fewest images
    roots = [copy_of(synthesised, tmp_path / f"s{i}", trials=("throw",)) for i in (1, 2)]
    deadline = time.monotonic() + 600
    started = []
    try:
        started.append(
            dask_command(
                "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                "--scheduler-file", str(tmp_path / "scheduler.json"),
                log=tmp_path / "scheduler.log",
            )
        )  # fmt: skip
        address = scheduler_address(tmp_path / "scheduler.json", time.monotonic() + 60)
        assert address.startswith("tcp://127.0.0.1:")
        started.append(
            dask_command(
                "worker", address, "--nthreads", "1", "--nworkers", "2", "--no-dashboard",
                "--host", "127.0.0.1", "--death-timeout", "60",
                log=tmp_path / "workers.log",
            )
        )  # fmt: skip
        result = subprocess.run(
            [sys.executable, "-m", "kisscal", "batch", *map(str, roots), "--scheduler", address],
            capture_output=True,
            text=True,
            timeout=max(deadline - time.monotonic(), 1),
            cwd=ROOT,
        )
    finally:
        for process in reversed(started):
            stop(process)
    logs = (tmp_path / "workers.log").read_text()[-2000:]
    assert result.returncode == 0, result.stdout + result.stderr[-2000:] + logs
    assert "2 of 2 sessions processed" in result.stderr  # the log, on stderr
    assert "daemonic" not in result.stdout + result.stderr
    for root in roots:
        summary = json.loads((root / "out" / "summary.json").read_text())
        assert list(summary["trials"]) == ["throw"]
        assert summary["trials"]["throw"]["trajectories"] == 1
        assert (root / "out" / "report.html").is_file()


def test_missing_dask_is_one_line_naming_the_extra(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "dask", None)  # import dask now fails
    with pytest.raises(
        KisscalError, match=r'^kisscal batch needs Dask: pip install "kisscal\[batch\]"$'
    ):
        # the function, not the module of the same name (an attribute of kisscal.session
        # once any test has imported it)
        importlib.import_module("kisscal.session.batch").batch([tmp_path])
