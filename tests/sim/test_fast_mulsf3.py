"""The firmware's float multiply (firmware/src/fast_mulsf3.S, linked in place of avr-libc's
__mulsf3) gives avr-libc's result bit for bit: the check image
(firmware/bench/mulsf3_check.cpp) multiplies pseudo-random pairs both ways in simavr (any bit
patterns, products around both ends of the normal range, rounding ties, products rounding up
into the next binade) and reports every mismatch."""
from __future__ import annotations

import struct

import pytest

from delta6.build import appbuild, avrbuild
from delta6.sim import avrsim, solverbench

PAIRS = 60_000
CHECK_SOURCES = (avrbuild.FIRMWARE / "bench" / "mulsf3_check.cpp",
                 avrbuild.FIRMWARE / "bench" / "mulsf3_reference.S",
                 avrbuild.FIRMWARE / "src" / "fast_mulsf3.S")


@pytest.fixture(scope="module")
def report():
    try:
        image = avrbuild.build_image("mulsf3-check", CHECK_SOURCES,
                                     defines=[f"DELTA6_CHECK_PAIRS={PAIRS}UL"], arduino=False)
        run = avrsim.run(image.elf, mcu=image.mcu, max_cycles=1_000_000_000)
    except (avrbuild.ToolchainMissing, avrsim.SimulatorError) as exc:
        pytest.fail(f"the AVR toolchain and simavr are required: {exc}")
    assert run.uart[:3] == b"MUL", run.uart
    return struct.unpack("<6I", run.uart[3:27])


def test_every_product_is_avr_libcs(report):
    pairs, mismatches, a, b, fast, reference = report
    assert pairs == PAIRS
    assert mismatches == 0, (f"{mismatches} of {pairs} differ; first: {a:#010x} * {b:#010x} "
                             f"= {fast:#010x}, avr-libc {reference:#010x}")


def test_the_firmware_and_the_solver_bench_link_it():
    """The application's sources and the solver benchmark's carry the fast multiply, so the
    benchmarks measure what the board runs."""
    fast = avrbuild.FIRMWARE / "src" / "fast_mulsf3.S"
    assert fast in appbuild.app_sources()
    assert fast in solverbench.CALIBRATED_SOURCES and fast in solverbench.SOLVER_SOURCES
