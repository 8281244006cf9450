"""Ctrl-C ends the workers of a pool left running, instead of waiting for its queue."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# A command interrupted while a pool it started still holds a queue of work: a stage
# whose pool is kept alive by the error's traceback, as a whole-suite run once saw.
_SCRIPT = textwrap.dedent(
    """
    import time
    from kisscal import _shared, cli

    @cli.app.command("stall")
    def stall() -> None:
        pool = _shared.worker_pool(1)
        queued = [pool.submit(time.sleep, 0.5) for _ in range(40)]
        queued[0].result()
        stall.kept = pool  # still referenced when the interrupt reaches main
        raise KeyboardInterrupt

    cli.main(["stall"])
    """
)


def test_an_interrupt_ends_a_pool_with_queued_work_at_once() -> None:
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-c", _SCRIPT], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    took_s = time.perf_counter() - start
    assert run.returncode == 130, run.stderr[-2000:]
    assert run.stderr.strip().splitlines()[-1] == "kisscal stall: error: interrupted"
    assert took_s < 10, took_s  # the queue alone holds 20 s of work
