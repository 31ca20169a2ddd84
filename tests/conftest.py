"""Shared fixtures. Optional extras (stable-baselines3, ray) skip where absent locally,
but are required in CI (CI=true): a skipped check there is a failure."""

from __future__ import annotations

import importlib
import os

import pytest


def require(module: str):
    """Import ``module``; skip without it locally, fail without it in CI."""
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        return importlib.import_module(module)
    return pytest.importorskip(module)


@pytest.fixture
def require_module():
    """The ``require`` helper as a fixture: ``require_module("stable_baselines3")``."""
    return require


@pytest.fixture(autouse=True)
def _headless(monkeypatch):
    monkeypatch.setenv("SDL_VIDEODRIVER", os.environ.get("SDL_VIDEODRIVER", "offscreen"))


# Property tests: a few examples in every run; `pytest --hypothesis-profile=slow -m property`
# runs 500 each (the acceptance run for the reliability targets).
try:
    from hypothesis import HealthCheck, settings

    settings.register_profile(
        "default", max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
    )
    settings.register_profile(
        "slow", max_examples=500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
    )
    settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))
except ImportError:  # hypothesis comes with the test extra
    pass
