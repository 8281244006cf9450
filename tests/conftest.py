"""Shared fixtures: small synthetic sessions written once per test run (once in all, even
when pytest-xdist spreads the tests over several processes)."""

from __future__ import annotations

# One BLAS thread in every test process, as the command line gives its own processes, set
# before NumPy loads: two test workers on two cores, each with a BLAS pool of two spinning
# threads, took twice the processor time for the wand route's many small products (a
# calibration of the wand session: 40-52 s of CPU against 22.5 s on one thread).
from kisscal.cli import blas  # noqa: F401  (first: before anything imports NumPy)

# isort: split
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from kisscal import session
from tests.once import built_once, shared_dir

# Property tests: a modest budget in every CI run, 10x with HYPOTHESIS_PROFILE=thorough.
settings.register_profile(
    "ci", max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "thorough", max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def small_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A six-camera KISS-like session, seed 3, 40-field gait trial, no walking5 replay.

    Shared by every test process of the run: tests copy it before changing anything."""
    return built_once(
        shared_dir(tmp_path_factory) / "small-s3",
        lambda out: session.synthesise(out, seed=3, fields=40, walking5=False, n_jobs=1),
    )


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Order and group the tests for the two CI workers (``-n 2 --dist loadgroup``).

    A module with a module-scoped fixture (a session synthesised and run for its tests)
    goes to one worker whole: split over two, both would build the fixture. So do the slow
    tests of the processed session of tests/session/conftest.py: the first of them (the
    bad-input tests) came to both workers at once, one waiting idle while the other built
    it (13 s). Modules with slow tests come first, so that the long tests start early and
    the workers end together.
    """
    slow_modules = set()
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        defs = info.name2fixturedefs if info is not None else {}
        shared = any(d.scope == "session" for d in defs.get("processed", ())[-1:])
        if shared and item.get_closest_marker("slow") is not None:
            item.add_marker(pytest.mark.xdist_group("processed-session"))
        elif any(d.scope == "module" for chain in defs.values() for d in chain):
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))
        if item.get_closest_marker("slow") is not None:
            slow_modules.add(item.nodeid.split("::")[0])
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in slow_modules)  # stable
