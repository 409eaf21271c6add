"""Shared test fixtures: the shipped designs and a hypothesis profile for CI."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parents[1]
DESIGNS = ROOT / "designs"
DESIGN_FILES = sorted(DESIGNS.glob("*.toml"))

settings.register_profile("default", deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("ci", parent=settings.get_profile("default"), max_examples=200,
                          print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def baseline():
    from delta6.design import load
    return load(DESIGNS / "delta6.toml")
