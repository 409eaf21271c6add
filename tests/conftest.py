"""Shared test fixtures: the shipped designs, a hypothesis profile for CI, and the markers.

Markers (registered in pyproject.toml): ``avr`` for tests that build AVR images or run simavr
(every test under tests/sim/ carries it); ``slow`` for the ones that take more than a few
seconds. The rule for a missing toolchain is one: the test FAILS with a line naming the Debian
package, because the README's setup (tools/bootstrap.sh) installs it; nothing is skipped.
"""
from __future__ import annotations

import os
import shutil
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
    from delta6.core.design import load
    return load(DESIGNS / "delta6.toml")


@pytest.fixture(scope="session")
def unit_logs(tmp_path_factory, baseline):
    """Two twin runs of one unit, (calibration log, evaluation log) (support/learned.py)."""
    from support import learned
    return learned.unit_logs(baseline, tmp_path_factory.mktemp("unit"))


@pytest.fixture(scope="session")
def tiny_models(tmp_path_factory, baseline, unit_logs):
    """One briefly trained model of each kind, exported: {kind: (path, fitted)}."""
    from support import learned
    return learned.tiny_models(baseline, unit_logs[0], tmp_path_factory.mktemp("models"))


#: What the ``avr`` tests need, and the Debian package that provides each.
AVR_TOOLS = {"avr-g++": "gcc-avr", "avr-gcc": "gcc-avr", "avr-size": "binutils-avr",
             "g++": "g++"}
AVR_FILES = {"/usr/include/simavr/sim_avr.h": "libsimavr-dev",
             "/usr/share/arduino/hardware/arduino/avr/cores/arduino": "arduino-core-avr",
             "/usr/lib/avr/include/avr/io.h": "avr-libc"}


def pytest_collection_modifyitems(config, items):
    sim_dir = Path(__file__).parent / "sim"
    for item in items:
        if sim_dir in Path(item.fspath).parents:
            item.add_marker(pytest.mark.avr)


def pytest_runtest_setup(item):
    if item.get_closest_marker("avr") is None:
        return
    missing = sorted({pkg for tool, pkg in AVR_TOOLS.items() if shutil.which(tool) is None}
                     | {pkg for path, pkg in AVR_FILES.items() if not Path(path).exists()})
    if missing:
        pytest.fail(f"AVR toolchain incomplete: install the Debian package(s) {', '.join(missing)} "
                    "(bash tools/bootstrap.sh does)", pytrace=False)
