"""The solver benchmark image (firmware/bench/solver_bench.cpp): build it, run it in simavr,
and decode what the AVR computed.

Shared by ``delta6 codegen --build``, tools/bench_solver_avr.py and the tests.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.build import avrbuild
from delta6.sim import avrsim

BENCH_SOURCE = avrbuild.FIRMWARE / "bench" / "solver_bench.cpp"
PROBE_SOURCE = avrbuild.FIRMWARE / "bench" / "solver_probe.cpp"
# The firmware's float multiply (firmware/src/fast_mulsf3.S) too: the benchmark measures what
# the board runs.
SOLVER_SOURCES = (avrbuild.CORE_LIB / "delta6_solver.cpp",
                  avrbuild.FIRMWARE / "src" / "fast_mulsf3.S")
CALIBRATED_SOURCES = (*SOLVER_SOURCES, avrbuild.CORE_LIB / "delta6_calibrated.cpp")
#: The solver's required accuracy, % of full scale per axis (docs/firmware.md, "Accuracy"):
#: the native tests and the AVR benchmark, analytical or calibrated, hold it to this.
REQUIRED_ACCURACY_PCT_FS = 0.01
SYNC = 0xD6
FRAMES = {  # type byte -> payload layout (little-endian, as the AVR stores it)
    ord("I"): struct.Struct("<IH24s"),
    ord("S"): struct.Struct("<6hB6f"),
    ord("E"): struct.Struct("<HH"),
}
MARK_START, MARK_STOP, MARK_CAL_START, MARK_CAL_STOP = 1, 2, 3, 4
#: Stage markers of the profile build (firmware/bench/delta6_solver_profile_hooks.h), in
#: order, with what the span ending at each covers.
STAGES = ((11, "joint terms: table trig, torques"), (12, "kinematics: linear elimination"),
          (13, "kinematics: quadratic, sqrt"), (14, "statics: levers, 3 divisions"),
          (15, "statics: link force sum"), (16, "rotation into {E}"),
          (MARK_STOP, "checks, output"))
#: The calibrated solver's stage markers (delta6_calibrated.cpp).
CALIBRATED_STAGES = ((21, "history, joint torques"), (22, "table trig, angle corrections"),
                     (23, "general trilateration"), (24, "statics"), (25, "gimbal, tilt"),
                     (MARK_STOP, "rotation into {E}, checks, output"))
#: The calibrated bench's sample period (kBenchPeriodS in solver_bench.cpp).
CALIBRATED_PERIOD_S = 0.004
#: The emulator's UART runs at 1 Mbaud (exact at 16 MHz with U2X) to keep runs short.
SIM_BAUD = 1_000_000


@dataclass
class BenchReport:
    design_name: str
    design_hash: int
    delta: np.ndarray        # (n, 6) int16 encoder deltas the AVR solved
    status: np.ndarray       # (n,) uint8
    wrench: np.ndarray       # (n, 6) float32 as the AVR computed it
    peak_stack: int          # bytes, high-water mark of the whole sketch
    static_ram: int          # bytes of .data + .bss as the AVR sees them


@dataclass
class BenchRun:
    report: BenchReport
    cycles: np.ndarray       # (n,) cycles per solve (marker overhead removed)
    image: avrbuild.Image
    stages: dict[str, np.ndarray] | None = None   # profile build: cycles per stage


def build_bench_image(include_dir: Path, *, name: str = "solver-bench", solves: int = 512,
                      baud: int = 115200, profile: bool = False, calibrated: bool = False,
                      out_dir: Path | None = None) -> avrbuild.Image:
    """The ATmega328P benchmark image for the design whose generated header lives under
    ``include_dir``/generated/. ``profile`` adds the solver's stage markers; ``calibrated``
    runs the calibrated solver with the calibration header next to the design header along a
    random walk; ``out_dir`` (default: a cache directory under build/avr/) is where the ELF
    and HEX go."""
    defines = [f"DELTA6_BENCH_SOLVES={solves}", f"DELTA6_BENCH_BAUD={baud}"]
    if calibrated:
        defines.append("DELTA6_BENCH_CALIBRATED")
    includes = [include_dir, avrbuild.CORE_LIB]
    if profile:
        defines.append("DELTA6_SOLVER_PROFILE")
        includes.append(BENCH_SOURCE.parent)
    sources = CALIBRATED_SOURCES if calibrated else SOLVER_SOURCES
    return avrbuild.build_image(name, [BENCH_SOURCE, *sources], include_dirs=includes,
                                defines=defines, out_dir=out_dir)


def build_probe(include_dir: Path, mcu: str, name: str = "solver-probe") -> avrbuild.Image:
    """The solver with nothing but a bare ``main`` around it (no Arduino core): what the
    solver and the float library cost in flash and static RAM on ``mcu``."""
    return avrbuild.size_check(f"{name}-{mcu}", [PROBE_SOURCE, *SOLVER_SOURCES],
                               include_dirs=[include_dir, avrbuild.CORE_LIB], mcu=mcu,
                               cxx_std="gnu++11")


def decode(data: bytes) -> BenchReport:
    """The sketch's frames -> report. Raises ValueError on anything unexpected."""
    frames: dict[int, list[tuple]] = {t: [] for t in FRAMES}
    pos = 0
    while pos < len(data):
        if pos + 2 > len(data) or data[pos] != SYNC or data[pos + 1] not in FRAMES:
            raise ValueError(f"bad frame header at byte {pos} of {len(data)}")
        layout = FRAMES[data[pos + 1]]
        if pos + 2 + layout.size > len(data):
            raise ValueError(f"truncated frame at byte {pos}")
        frames[data[pos + 1]].append(layout.unpack_from(data, pos + 2))
        pos += 2 + layout.size
    info, solves, end = frames[ord("I")], frames[ord("S")], frames[ord("E")]
    if len(info) != 1 or len(end) != 1:
        raise ValueError("expected one info frame and one end frame")
    design_hash, count, name = info[0]
    if len(solves) != count:
        raise ValueError(f"the AVR announced {count} solves and sent {len(solves)}")
    rows = np.array([r[:7] for r in solves], dtype=np.int64).reshape(-1, 7)
    return BenchReport(
        design_name=name.rstrip(b"\0").decode("ascii", "replace"), design_hash=design_hash,
        delta=rows[:, :6].astype(np.int16), status=rows[:, 6].astype(np.uint8),
        wrench=np.array([r[7:] for r in solves], dtype=np.float32).reshape(-1, 6),
        peak_stack=end[0][0], static_ram=end[0][1])


def run_bench(include_dir: Path, *, solves: int = 512, name: str = "solver-bench-sim",
              profile: bool = False, calibrated: bool = False) -> BenchRun:
    """Build the benchmark for the design under ``include_dir``, run it in simavr, decode.
    With ``profile`` the solver carries stage markers (a few cycles each) and the run also
    returns the cycles of each stage of every successful solve; ``calibrated``: the
    calibrated solver (see :func:`build_bench_image`)."""
    image = build_bench_image(include_dir, name=name, solves=solves, baud=SIM_BAUD,
                              profile=profile, calibrated=calibrated)
    result = avrsim.run(image.elf, mcu=image.mcu)
    try:
        report = decode(result.uart)
    except ValueError as exc:
        raise avrsim.SimulatorError(f"unreadable benchmark output: {exc}") from None
    spans = np.array(result.spans(MARK_START, MARK_STOP), dtype=np.int64)
    overhead = result.spans(MARK_CAL_START, MARK_CAL_STOP)
    if len(spans) != solves or len(overhead) != 1:
        raise avrsim.SimulatorError(f"expected {solves} timed solves, the simulator saw "
                                    f"{len(spans)}")
    stages = (_stage_spans(result.markers, CALIBRATED_STAGES if calibrated else STAGES)
              if profile else None)
    return BenchRun(report, spans - overhead[0], image, stages)


def _stage_spans(markers: list[tuple[int, int]], stages=STAGES) -> dict[str, np.ndarray]:
    """Cycles between consecutive stage markers within each solve that ran every stage."""
    order = [MARK_START] + [m for m, _ in stages]
    per_solve, current = [], None
    for cycle, value in markers:
        if value == MARK_START:
            current = [cycle]
        elif current is not None and len(current) < len(order) and value == order[len(current)]:
            current.append(cycle)
            if len(current) == len(order):
                per_solve.append(np.diff(current))
                current = None
    table = np.array(per_solve, dtype=np.int64).reshape(-1, len(stages))
    return {label: table[:, i] for i, (_, label) in enumerate(stages)}
