"""Ctrl-C during ``kisscal run``: one ``interrupted`` line, exit 130, no worker traceback."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _as_a_terminal_starts_it() -> None:
    # A shell starts a foreground job with Ctrl-C at its default; a test process may
    # ignore it (a pytest-xdist worker of the whole suite does), and an ignored SIGINT
    # is inherited: Python would then never raise KeyboardInterrupt in the run.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _press_ctrl_c(run: subprocess.Popen) -> tuple[str, str, float]:
    """Ctrl-C to the run's process group; a second one if the first went unheard.

    Twice in whole-suite runs the run went on after one Ctrl-C (0.5 s in, both cores busy):
    CPython drops a KeyboardInterrupt that its signal handler raises where errors are
    discarded (a finaliser, a callback after a fork). The CLI raises it again
    (``kisscal.cli._keep_interrupts``, tested in ``test_interrupt_pool.py``); a user who
    is not heard presses again, and so does this test.
    """
    for _ in range(2):
        sent = time.perf_counter()
        os.killpg(run.pid, signal.SIGINT)
        try:
            out, err = run.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            continue
        return out, err, time.perf_counter() - sent
    out, err = run.communicate(timeout=120)
    return out, err, time.perf_counter() - sent


@pytest.mark.slow
@pytest.mark.parametrize("after_s", [0.5, 3.0])
def test_ctrl_c_stops_run_with_one_line(
    small_session: Path, tmp_path: Path, after_s: float
) -> None:
    root = tmp_path / "s"
    shutil.copytree(small_session, root, ignore=shutil.ignore_patterns("out"))
    # its own process group, as a terminal's foreground job: Ctrl-C reaches every process
    run = subprocess.Popen(
        [sys.executable, "-m", "kisscal", "run", str(root)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        cwd=ROOT,
        preexec_fn=_as_a_terminal_starts_it,
    )
    assert run.stderr is not None
    first = run.stderr.readline()  # the pipeline has started (worker pools come next)
    assert first.startswith("[1/4]"), first
    time.sleep(after_s)
    out, err, stopped_s = _press_ctrl_c(run)
    assert run.returncode == 130, err[-3000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-3000:]
    lines = err.strip().splitlines()
    assert lines[-1] == "kisscal run: error: interrupted", lines[-3:]
    assert sum("error" in line for line in lines) == 1
    assert out == ""
    assert stopped_s < 10, stopped_s  # the workers are ended, not waited for
