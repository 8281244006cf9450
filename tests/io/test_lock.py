"""One writer per session: a second process is refused, the same process may nest."""

from __future__ import annotations

import os
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


def _refused_while_held(script: str, out: Path) -> None:
    """A process running ``script`` holds ``out``'s lock: this one is refused, naming the
    holder's pid, until the holder dies."""
    holder = subprocess.Popen(
        [sys.executable, "-c", script, str(out)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(KisscalError, match=rf"another kisscal process \(pid {holder.pid}\)"):
            with session_lock(out):
                pass
    finally:
        holder.kill()
        holder.wait()


def test_second_process_is_refused_and_nesting_is_allowed(tmp_path: Path) -> None:
    out = tmp_path / "out"
    _refused_while_held(HOLD, out)
    with session_lock(out), session_lock(out):  # released by the holder's death; re-entrant
        pass


def test_unwritable_output_folder_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("a file where the session folder should be")
    with pytest.raises(KisscalError, match="cannot write the output folder"):
        with session_lock(blocker / "out"):
            pass


# Windows has no fcntl: the lock is msvcrt.locking of one byte. Linux has no msvcrt, so the
# test stands in for it with POSIX record locks of the same byte range (non-blocking lock
# fails with OSError, released by unlocking or by the process's end, as Windows does);
# what it checks is kisscal's use of the msvcrt calls: offset, mode, release, message.
FAKE_MSVCRT = """
import fcntl, os, types
def locking(fd, mode, nbytes):
    start = os.lseek(fd, 0, os.SEEK_CUR)
    calls.append((mode, start, nbytes))
    op = fcntl.LOCK_UN if mode == LK_UNLCK else fcntl.LOCK_EX | fcntl.LOCK_NB
    fcntl.lockf(fd, op, nbytes, start)
calls = []
LK_UNLCK, LK_NBLCK = 0, 2
fake = types.SimpleNamespace(locking=locking, LK_UNLCK=LK_UNLCK, LK_NBLCK=LK_NBLCK, calls=calls)
"""

HOLD_WINDOWS = (
    FAKE_MSVCRT
    + """
import sys, time
import kisscal.io.lock as lock
lock.fcntl, lock.msvcrt = None, fake
with lock.session_lock(sys.argv[1]):
    print("held", flush=True)
    time.sleep(30)
"""
)


def fake_msvcrt():
    scope: dict = {}
    exec(FAKE_MSVCRT, scope)
    return scope["fake"]


def test_without_fcntl_the_lock_is_msvcrt_s(tmp_path: Path, monkeypatch) -> None:
    import kisscal.io.lock as lock

    fake = fake_msvcrt()
    monkeypatch.setattr(lock, "fcntl", None)
    monkeypatch.setattr(lock, "msvcrt", fake)
    out = tmp_path / "out"
    _refused_while_held(HOLD_WINDOWS, out)
    with session_lock(out), session_lock(out):  # released by the holder's death; re-entrant
        assert (out / ".lock").read_text() == f"pid {os.getpid()}"
    # one byte past the holder's text locked, then unlocked before the file is closed
    lock_byte = (lock.MSVCRT_BYTE, 1)
    assert [c[1:] for c in fake.calls] == [lock_byte] * 3
    assert [c[0] for c in fake.calls] == [fake.LK_NBLCK, fake.LK_NBLCK, fake.LK_UNLCK]


def test_without_any_lock_runs_are_not_guarded(tmp_path: Path, monkeypatch) -> None:
    import kisscal.io.lock as lock

    monkeypatch.setattr(lock, "fcntl", None)
    monkeypatch.setattr(lock, "msvcrt", None)
    with session_lock(tmp_path / "out"):
        assert (tmp_path / "out" / ".lock").is_file()
