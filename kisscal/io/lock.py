"""One writer per session: an advisory lock on ``out/.lock``.

Two kisscal processes writing into the same ``out/`` would interleave their outputs; the
second one is refused with a message naming the holder. The lock is the operating
system's, so it is released when its process ends, even by a crash: ``flock`` on Linux
and macOS; on Windows, where there is no ``fcntl``, ``msvcrt.locking`` of one byte of the
file, placed past the holder's text (a locked byte cannot be read by other processes,
the text must be). Taking it creates ``out/`` first, which also finds an unwritable
session before any work is done. Within one process the lock is re-entrant
(``kisscal run`` calls the other stages).
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from kisscal.errors import InputError, KisscalError

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None  # type: ignore[assignment]
try:
    import msvcrt
except ImportError:  # Linux, macOS
    msvcrt = None  # type: ignore[assignment]

#: Offset of the byte of ``.lock`` that ``msvcrt.locking`` locks (beyond the holder's text;
#: Windows lets a lock lie past the end of a file).
MSVCRT_BYTE = 1 << 20

_HELD: dict[Path, int] = {}
_GUARD = threading.Lock()


@contextlib.contextmanager
def session_lock(out: Path) -> Iterator[None]:
    """Hold the write lock of the output folder ``out`` for the block.

    Raises
    ------
    KisscalError
        ``out`` cannot be created or written, or another process holds the lock.
    """
    out = Path(out).resolve()
    with _GUARD:
        if out in _HELD:
            _HELD[out] += 1
            held_here = True
        else:
            held_here = False
    if held_here:
        try:
            yield
        finally:
            with _GUARD:
                _HELD[out] -= 1
        return
    fd = _acquire(out)
    with _GUARD:
        _HELD[out] = 1
    try:
        yield
    finally:
        with _GUARD:
            del _HELD[out]
        _release(fd)


def _acquire(out: Path) -> int:
    try:
        out.mkdir(exist_ok=True)
        fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise InputError(f"{out}: cannot write the output folder ({exc.strerror})") from None
    if not _lock(fd):
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        # the base class: none of the three kinds; the session is busy, not wrong
        raise KisscalError(
            f"{out}: another kisscal process ({holder}) is writing this session; "
            "wait for it to finish"
        ) from None
    os.ftruncate(fd, 0)
    os.write(fd, f"pid {os.getpid()}".encode())
    return fd


def _lock(fd: int) -> bool:
    """Take the operating system's lock on ``fd`` without waiting: False when another
    process holds it. Where the system has neither lock, runs are not guarded."""
    if fcntl is not None:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return False
        return True
    if msvcrt is not None:
        os.lseek(fd, MSVCRT_BYTE, os.SEEK_SET)
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        except OSError:
            return False
        finally:
            os.lseek(fd, 0, os.SEEK_SET)
    return True


def _release(fd: int) -> None:
    """Give the lock back and close ``fd`` (closing alone releases ``flock``; Windows may
    release a closed file's locks late, so they are released first)."""
    if fcntl is None and msvcrt is not None:
        os.lseek(fd, MSVCRT_BYTE, os.SEEK_SET)
        with contextlib.suppress(OSError):
            msvcrt.locking(fd, msvcrt.LK_UNLCK, 1)
    os.close(fd)
