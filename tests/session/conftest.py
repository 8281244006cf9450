"""One four-camera session (seed 7, 20 fields) for the end-to-end tests of this folder,
synthesised once and processed once per test run, even when pytest-xdist spreads the tests
over several processes: the slowest tests (spawned workers, the Dask batches, the bad-input
catalogue) used to synthesise and run sessions of their own that differed in nothing they
check. Each test copies the session it is given before changing anything."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import tomli_w

from kisscal import session
from kisscal.io.config import load_toml
from tests.once import built_once, shared_dir


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
