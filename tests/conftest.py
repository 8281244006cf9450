"""Shared fixtures: small synthetic sessions written once per test process."""

from __future__ import annotations

from pathlib import Path

import pytest

from kisscal import session


@pytest.fixture(scope="session")
def small_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A six-camera KISS-like session, seed 3, 40-field gait trial, no walking5 replay."""
    out = tmp_path_factory.mktemp("synth") / "s3"
    return session.synthesise(out, seed=3, fields=40, walking5=False, n_jobs=1)
