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


# A Ctrl-C that Python raises where it cannot propagate (a finaliser; after a fork, the
# logging lock's release): printed as "Exception ignored" and dropped, unless kept.
_LOST = textwrap.dedent(
    """
    import signal
    import time
    from kisscal import cli

    signal.signal(signal.SIGINT, signal.default_int_handler)  # as at a terminal

    class Finalised:
        def __del__(self) -> None:
            raise KeyboardInterrupt

    @cli.app.command("busy")
    def busy() -> None:
        Finalised()
        start = time.perf_counter()
        while time.perf_counter() - start < 20:
            pass
        print("went on")

    cli.main(["busy"])
    """
)


def test_an_interrupt_raised_in_a_finaliser_still_stops_the_command() -> None:
    run = subprocess.run(
        [sys.executable, "-c", _LOST], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    assert run.returncode == 130, run.stderr[-2000:]
    assert "went on" not in run.stdout
    assert run.stderr.strip().splitlines() == ["kisscal busy: error: interrupted"], run.stderr
