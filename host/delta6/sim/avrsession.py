"""The scripted session of firmware/native/avr_session.cpp, on the emulated AVR and natively.

The same device core, the same inputs: the emulated ATmega328P (avr-gcc 5.4, avr-libc float
with the application's multiply) must send exactly the bytes the native build (host g++, the
one every other test and the simulated device use) sends. Also the source of the AVR cycle
figures of the benchmark.
"""
from __future__ import annotations

import numpy as np

from delta6.build import avrbuild, nativebuild
from delta6.link import protocol as P
from delta6.sim import avrsim
from delta6.sim.simdevice import NativeCore

SOURCE = nativebuild.FIRMWARE_NATIVE / "avr_session.cpp"
FULL_SCALE = np.array([15.03, 15.03, 25.1, 0.3805, 0.3347, 0.4266], dtype=np.float32)
ZERO = np.array([1200, 5400, 9800, 14100, 300, 16000])
#: marker -> what the span times (avr_session.cpp)
SPANS = {80: "begin", 10: "stopped", 50: "start", 20: "wrench", 52: "set_mode", 30: "raw",
         54: "tare", 56: "averaging", 40: "raw_tared", 60: "get_info", 62: "get_telemetry"}
SCRIPT = [("samples", 20), ("command", (P.Command.START, 0x22, 500)), ("samples", 50),
          ("command", (P.Command.SET_MODE, 0x24, 2)), ("samples", 50),
          ("command", (P.Command.TARE, 0x25, 10)), ("samples", 10), ("samples", 50),
          ("command", (P.Command.GET_INFO, 0x20)), ("command", (P.Command.GET_TELEMETRY, 0x2B))]


#: The application's float multiply (avr-libc's results, faster): the session's cycles are
#: the board's.
FAST_MULTIPLY = avrbuild.FIRMWARE / "src" / "fast_mulsf3.S"


def run_on_avr() -> avrsim.AvrRun:
    image = avrbuild.build_image("protocol_session",
                                 [SOURCE, FAST_MULTIPLY, *nativebuild.core_sources()],
                                 [nativebuild.FIRMWARE_CORE], arduino=False)
    return avrsim.run(image.elf, max_cycles=50_000_000, timeout_s=60)


def cycles(result: avrsim.AvrRun) -> dict[str, float]:
    """Mean cycles of each timed call."""
    return {name: float(np.mean(result.spans(m, m + 1))) for m, name in SPANS.items()}


def run_natively() -> bytes:
    core = NativeCore(design_name="delta6", design_hash=0x535534AF, full_scale=FULL_SCALE,
                      joint_limit_rad=0.5236, joint_limit_counts=1365, baud=500_000, max_rate_hz=2000,
                      default_rate_hz=500, zero_counts=ZERO, serial_number=0,
                      tx_capacity=65535)
    core.set_time(0)
    core.begin(0)
    out = [core.read()]
    f32 = np.float32
    wrench = np.array([f32(1.5) * f32(i + 1) - f32(4) for i in range(6)], dtype=f32)
    counts = ZERO + 100 * np.arange(6)
    t = 0
    for kind, arg in SCRIPT:
        if kind == "command":
            out.append(_feed(core, P.encode_command(*arg)))
            continue
        for _ in range(arg):       # float32 steps, as the AVR adds them
            t += 2000
            wrench[0] += f32(0.0137)
            wrench[2] -= f32(0.021)
            wrench[4] += f32(0.0003)
            core.samples([t], counts[None], [0], [1], wrench[None], [0], [900])
            out.append(core.read())
    core.close()
    return b"".join(out)


def _feed(core: NativeCore, frame: bytes) -> bytes:
    core.feed(frame)
    return core.read()
