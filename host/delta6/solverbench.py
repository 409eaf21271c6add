"""The solver benchmark image (firmware/bench/solver_bench.cpp): build it, run it in simavr,
and decode what the AVR computed.

Shared by ``delta6 codegen --build``, tools/bench_solver_avr.py and the tests.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import avrbuild, avrsim

BENCH_SOURCE = avrbuild.FIRMWARE / "bench" / "solver_bench.cpp"
SOLVER_SOURCES = (avrbuild.CORE_LIB / "delta6_solver.cpp",)
FRAME = struct.Struct("<2s6hB6f")
SYNC = b"\xd6\x5a"
MARK_START, MARK_STOP, MARK_CAL_START, MARK_CAL_STOP = 1, 2, 3, 4
#: The emulator's UART runs at 1 Mbaud (exact at 16 MHz with U2X) to keep runs short.
SIM_BAUD = 1_000_000


@dataclass
class BenchRun:
    delta: np.ndarray      # (n, 6) int16 encoder deltas the AVR solved
    status: np.ndarray     # (n,) uint8
    wrench: np.ndarray     # (n, 6) float32 as the AVR computed it
    cycles: np.ndarray     # (n,) cycles per solve (marker overhead removed)
    image: avrbuild.Image


def build_bench_image(include_dir: Path, *, name: str = "solver-bench", solves: int = 512,
                      baud: int = 115200) -> avrbuild.Image:
    """The ATmega328P benchmark image for the design whose generated header lives under
    ``include_dir``/generated/."""
    return avrbuild.build_image(
        name, [BENCH_SOURCE, *SOLVER_SOURCES],
        include_dirs=[include_dir, avrbuild.CORE_LIB],
        defines=[f"DELTA6_BENCH_SOLVES={solves}", f"DELTA6_BENCH_BAUD={baud}"])


def decode_frames(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames sent by the sketch -> (delta, status, wrench). Raises ValueError on garbage."""
    if len(data) % FRAME.size:
        raise ValueError(f"{len(data)} UART bytes is not a whole number of "
                         f"{FRAME.size}-byte frames")
    rows = [FRAME.unpack_from(data, off) for off in range(0, len(data), FRAME.size)]
    if any(r[0] != SYNC for r in rows):
        raise ValueError("frame without sync bytes in the UART stream")
    delta = np.array([r[1:7] for r in rows], dtype=np.int16).reshape(-1, 6)
    status = np.array([r[7] for r in rows], dtype=np.uint8)
    wrench = np.array([r[8:14] for r in rows], dtype=np.float32).reshape(-1, 6)
    return delta, status, wrench


def run_bench(include_dir: Path, *, solves: int = 512, name: str = "solver-bench-sim") -> BenchRun:
    image = build_bench_image(include_dir, name=name, solves=solves, baud=SIM_BAUD)
    result = avrsim.run(image.elf, mcu=image.mcu)
    delta, status, wrench = decode_frames(result.uart)
    spans = np.array(result.spans(MARK_START, MARK_STOP), dtype=np.int64)
    overhead = result.spans(MARK_CAL_START, MARK_CAL_STOP)
    if len(spans) != solves or len(delta) != solves or len(overhead) != 1:
        raise avrsim.SimulatorError(f"benchmark reported {len(delta)} frames and {len(spans)} "
                                    f"timed solves, expected {solves}")
    return BenchRun(delta, status, wrench, spans - overhead[0], image)
