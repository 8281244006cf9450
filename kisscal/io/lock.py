"""One writer per session: an advisory lock on ``out/.lock``.

Two kisscal processes writing into the same ``out/`` would interleave their outputs; the
second one is refused with a message naming the holder. The lock is the operating
system's (``flock``), so it is released when its process ends, even by a crash. Taking it
creates ``out/`` first, which also finds an unwritable session before any work is done.
Within one process the lock is re-entrant (``kisscal run`` calls the other stages).
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from kisscal.errors import KisscalError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: no advisory locks, runs are not guarded
    fcntl = None  # type: ignore[assignment]

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
        os.close(fd)  # closing the descriptor releases the lock


def _acquire(out: Path) -> int:
    try:
        out.mkdir(exist_ok=True)
        fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise KisscalError(f"{out}: cannot write the output folder ({exc.strerror})") from None
    if fcntl is None:  # pragma: no cover
        return fd
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise KisscalError(
            f"{out}: another kisscal process ({holder}) is writing this session; "
            "wait for it to finish"
        ) from None
    os.ftruncate(fd, 0)
    os.write(fd, f"pid {os.getpid()}".encode())
    return fd
