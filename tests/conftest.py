"""Shared fixtures: small synthetic sessions written once per test process."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from kisscal import session

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
    """A six-camera KISS-like session, seed 3, 40-field gait trial, no walking5 replay."""
    out = tmp_path_factory.mktemp("synth") / "s3"
    return session.synthesise(out, seed=3, fields=40, walking5=False, n_jobs=1)
