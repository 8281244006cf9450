"""One four-camera session (seed 7, 20 fields) for the end-to-end tests of this folder,
synthesised once and processed once per test run, even when pytest-xdist spreads the tests
over several processes: the slowest tests (spawned workers, the Dask batches, the bad-input
catalogue) used to synthesise and run sessions of their own that differed in nothing they
check. Each test copies the session it is given before changing anything."""

from __future__ import annotations

import os
import shutil
import time
import traceback
from collections.abc import Callable
from pathlib import Path

import pytest
import tomli_w

from kisscal import session
from kisscal.io.config import load_toml

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


@pytest.fixture(scope="session")
def synthesised(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Seed 7, four cameras, walk01 of 20 fields, stick and throw; not processed."""
    return built_once(
        shared_dir(tmp_path_factory) / "seed7-synthesised",
        lambda root: session.synthesise(
            root, seed=7, fields=20, n_cameras=4, walking5=False, n_jobs=1
        ),
    )


@pytest.fixture(scope="session")
def processed(synthesised: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The seed-7 session processed by ``kisscal run`` with two worker processes started
    the platform's default way (forked where the system can fork)."""

    def build(root: Path) -> None:
        shutil.copytree(synthesised, root)
        session.run(root, workers=2)

    return built_once(shared_dir(tmp_path_factory) / "seed7-processed", build)


def copy_of(src: Path, dest: Path, trials: tuple[str, ...] | None = None) -> Path:
    """A copy of the session ``src`` (without ``out/``) at ``dest``; with ``trials``, only
    those trials are left in its ``session.toml``."""
    shutil.copytree(src, dest, ignore=shutil.ignore_patterns("out"))
    if trials is not None:
        config = load_toml(dest / "session.toml")
        config["trials"] = [t for t in config["trials"] if t["name"] in trials]
        assert [t["name"] for t in config["trials"]] == list(trials)
        (dest / "session.toml").write_text(tomli_w.dumps(config))
    return dest
