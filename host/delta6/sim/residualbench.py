"""The residual engine on the ATmega328P in simavr (firmware/bench/residual_bench.cpp): build
the sketch for a model header, run it, decode the corrections the AVR computed and the cycles
of each step, and regenerate the sketch's input stream for the numpy reference.

Used by the AVR cross-check test and tools/bench_residual.py.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.build import avrbuild
from delta6.sim import avrsim

BENCH_SOURCE = avrbuild.FIRMWARE / "bench" / "residual_bench.cpp"
ENGINE = avrbuild.CORE_LIB / "delta6_residual.cpp"
SYNC = 0xD6
FRAMES = {ord("I"): struct.Struct("<IHHB"), ord("S"): struct.Struct("<B6h"),
          ord("E"): struct.Struct("<HH")}
SIM_BAUD = 1_000_000


@dataclass
class ResidualRun:
    model_hash: int
    board_rate_hz: int
    stride: int
    valid: np.ndarray          # (n,) bool
    correction: np.ndarray     # (n, 6) int16 as the AVR computed them
    cycles: np.ndarray         # (k,) cycles of each step (markers removed)
    peak_stack: int
    static_ram: int
    image: avrbuild.Image


def stream(samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sketch's inputs: base (n, 6), counts (n, 6), valid (n,), from its xorshift."""
    state = 0xACE1

    def rnd() -> int:
        nonlocal state
        state ^= (state << 7) & 0xFFFF
        state ^= state >> 9
        state ^= (state << 8) & 0xFFFF
        return state

    def walk(x: int, bits: int, limit: int) -> int:
        step = (rnd() >> (16 - bits)) - (1 << (bits - 1))
        return max(-limit, min(limit, x + step))

    base = np.zeros((samples, 6), dtype=np.int64)
    counts = np.zeros((samples, 6), dtype=np.int64)
    valid = np.zeros(samples, dtype=bool)
    b, c = [0] * 6, [0] * 6
    for i in range(samples):
        for j in range(6):
            b[j] = walk(b[j], 10, 30000)
            c[j] = walk(c[j], 4, 1400)
        base[i], counts[i] = b, c
        valid[i] = (rnd() & 63) != 0
    return base, counts, valid


def build(include_dir: Path, *, samples: int, rate_hz: int) -> avrbuild.Image:
    defines = [f"DELTA6_BENCH_SAMPLES={samples}", f"DELTA6_BENCH_BAUD={SIM_BAUD}",
               f"DELTA6_BENCH_RATE_HZ={rate_hz}"]
    return avrbuild.build_image("residual-bench", [BENCH_SOURCE, ENGINE],
                                include_dirs=[include_dir, avrbuild.CORE_LIB], defines=defines)


def run(include_dir: Path, *, samples: int = 2000, rate_hz: int = 250) -> ResidualRun:
    """Build the sketch for the model header under ``include_dir``/generated/, run, decode."""
    image = build(include_dir, samples=samples, rate_hz=rate_hz)
    result = avrsim.run(image.elf, mcu=image.mcu)
    frames = _frames(result.uart)
    info, rows, end = frames[ord("I")], frames[ord("S")], frames[ord("E")]
    if len(info) != 1 or len(end) != 1 or len(rows) != samples:
        raise avrsim.SimulatorError(f"expected {samples} samples from the AVR, got {len(rows)}")
    table = np.array(rows, dtype=np.int64).reshape(-1, 7)
    spans = np.array(result.spans(1, 2), dtype=np.int64)
    overhead = result.spans(3, 4)
    return ResidualRun(model_hash=info[0][0], board_rate_hz=info[0][2], stride=info[0][3],
                       valid=table[:, 0].astype(bool), correction=table[:, 1:],
                       cycles=spans - overhead[0], peak_stack=end[0][0], static_ram=end[0][1],
                       image=image)


def _frames(data: bytes) -> dict[int, list[tuple]]:
    frames: dict[int, list[tuple]] = {t: [] for t in FRAMES}
    pos = 0
    while pos < len(data):
        if pos + 2 > len(data) or data[pos] != SYNC or data[pos + 1] not in FRAMES:
            raise avrsim.SimulatorError(f"unreadable benchmark output at byte {pos}")
        layout = FRAMES[data[pos + 1]]
        if pos + 2 + layout.size > len(data):
            raise avrsim.SimulatorError(f"truncated frame at byte {pos}")
        frames[data[pos + 1]].append(layout.unpack_from(data, pos + 2))
        pos += 2 + layout.size
    return frames
