"""Run AVR firmware in simavr and read back what it reported.

The runner is a small C program on libsimavr (``tools/simavr/delta6_sim.c``), built with the
host compiler by the one compile helper and cached under ``build/simavr/``. It records two channels, both stamped
by the simulator: GPIOR0 writes (cycle markers that bracket timed code) and the bytes the
firmware sends on UART0. See the C file for the command line.
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from delta6.build import compilecache
from delta6.build.avrbuild import NANO
from delta6.core.errors import UserError
from delta6.core.paths import REPO_ROOT

HARNESS_SOURCE = REPO_ROOT / "tools" / "simavr" / "delta6_sim.c"
TOOL_FLAGS = ("-O2", "-Wall", "-Wextra", "-Werror", "-std=gnu11")
SIMAVR_LIBS = ("-lsimavr", "-lsimavrparts", "-lutil", "-lpthread", "-lm")
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")
APT_HINT = ("install it with: sudo apt-get install --no-install-recommends simavr "
            "libsimavr-dev (or run bash tools/bootstrap.sh)")


class SimulatorError(UserError):
    """simavr is missing, or the firmware did not finish as expected."""


@dataclass
class AvrRun:
    """One firmware run in simavr: its cycle markers and everything it sent on the UART."""

    markers: list[tuple[int, int]]   # (cycle, value) of every GPIOR0 write, in order
    uart: bytes                      # everything UART0 transmitted
    stderr: str

    def spans(self, start: int, stop: int) -> list[int]:
        """Cycles between each ``start`` marker and the ``stop`` marker that follows it."""
        out, opened = [], None
        for cycle, value in self.markers:
            if value == start:
                opened = cycle
            elif value == stop and opened is not None:
                out.append(cycle - opened)
                opened = None
        return out


def build_tool(name: str, sources, depends=(), error=None) -> Path:
    """Compile a C program on libsimavr with the host compiler into build/simavr/NAME-KEY
    (:mod:`delta6.build.compilecache`: rebuilt when a source, a header beside it, a file in
    ``depends``, a flag or the compiler changes). Raises ``error`` (default
    :class:`SimulatorError`) with one line saying what to install."""
    error = error or SimulatorError
    cc = shutil.which("gcc") or shutil.which("cc")
    if not cc:
        raise error("no host C compiler (gcc) found; install gcc")
    if not SIMAVR_HEADER.exists():
        raise error(f"simavr headers not found; {APT_HINT}")
    return compilecache.build_program(name, sources, compiler=cc, flags=TOOL_FLAGS,
                                      libs=SIMAVR_LIBS, depends=depends, area="simavr",
                                      error=error)


def harness() -> Path:
    """Path of the compiled runner (built on first use, rebuilt when its source changes)."""
    return build_tool("delta6_sim", [HARNESS_SOURCE])


def run(elf: Path, *, mcu: str = NANO.mcu, freq: int = NANO.f_cpu,
        max_cycles: int = 200_000_000, stop_marker: int = 0xFF,
        timeout_s: float | None = 300.0) -> AvrRun:
    """Run ``elf`` until it writes ``stop_marker`` to GPIOR0; raise if it never does."""
    exe = harness()
    with tempfile.TemporaryDirectory(prefix="delta6-sim-") as tmp:
        uart, markers = Path(tmp) / "uart.bin", Path(tmp) / "markers.txt"
        cmd = [str(exe), str(elf), "--mcu", mcu, "--freq", str(freq), "--max-cycles",
               str(max_cycles), "--stop-marker", str(stop_marker), "--uart", str(uart),
               "--markers", str(markers)]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise SimulatorError(f"simulation of {elf.name} exceeded {timeout_s:g} s") from None
        if proc.returncode != 0:
            raise SimulatorError(f"simulation of {elf.name} failed (status {proc.returncode}): "
                                 f"{proc.stderr.strip()}")
        pairs = []
        for line in markers.read_text().splitlines():
            cycle, value = line.split()
            pairs.append((int(cycle), int(value)))
        return AvrRun(markers=pairs, uart=uart.read_bytes(), stderr=proc.stderr)
