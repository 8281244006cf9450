"""One writer per session: a second process is refused, the same process may nest."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from kisscal.errors import KisscalError
from kisscal.io.lock import session_lock

HOLD = """
import sys, time
from kisscal.io.lock import session_lock
with session_lock(sys.argv[1]):
    print("held", flush=True)
    time.sleep(30)
"""


def test_second_process_is_refused_and_nesting_is_allowed(tmp_path: Path) -> None:
    out = tmp_path / "out"
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(out)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(KisscalError, match=r"another kisscal process \(pid \d+\)"):
            with session_lock(out):
                pass
    finally:
        holder.kill()
        holder.wait()
    with session_lock(out), session_lock(out):  # released by the holder's death; re-entrant
        pass


def test_unwritable_output_folder_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file where the session folder should be")
    with pytest.raises(KisscalError, match="cannot write the output folder"):
        with session_lock(blocker / "out"):
            pass
