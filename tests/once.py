"""Test inputs built once per test run, even when pytest-xdist spreads the tests over
several processes (each of which would otherwise build its own session-scoped fixtures)."""

from __future__ import annotations

import os
import time
import traceback
from collections.abc import Callable
from pathlib import Path

import pytest

#: How long a test process waits for another one to build a shared session.
WAIT_S = 1800.0


def shared_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder every test process of this run sees: the parent of the per-worker
    temporary folders under pytest-xdist, this process' own otherwise."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def built_once(path: Path, build: Callable[[Path], object]) -> Path:
    """``path``, built by ``build(folder)`` in the first test process to ask for it.

    The first process claims it (``mkdir`` is atomic), builds it beside and renames it
    into place; the others wait for the rename. A failed build leaves its traceback in
    ``<path>.failed``, which fails the waiting tests too.
    """
    claim, work = path.with_name(path.name + ".claim"), path.with_name(path.name + ".part")
    failed = path.with_name(path.name + ".failed")
    try:
        claim.mkdir(parents=True)
    except FileExistsError:
        deadline = time.monotonic() + WAIT_S
        while not path.is_dir():
            if failed.is_file():
                pytest.fail(f"building {path.name} failed:\n{failed.read_text()}")
            if time.monotonic() > deadline:
                pytest.fail(f"{path.name} was not built within {WAIT_S:.0f} s")
            time.sleep(0.5)
        return path
    try:
        build(work)
    except BaseException:
        failed.write_text(traceback.format_exc())
        raise
    work.rename(path)
    return path
