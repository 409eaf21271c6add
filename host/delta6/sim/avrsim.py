"""Run AVR firmware in simavr and read back what it reported.

The runner is a small C program on libsimavr (``tools/simavr/delta6_sim.c``), built here with
the host compiler and cached under ``build/simavr/``. It records two channels, both stamped
by the simulator: GPIOR0 writes (cycle markers that bracket timed code) and the bytes the
firmware sends on UART0. See the C file for the command line.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from delta6.build.avrbuild import REPO_ROOT
from delta6.core.errors import UserError

HARNESS_SOURCE = REPO_ROOT / "tools" / "simavr" / "delta6_sim.c"
BUILD_DIR = REPO_ROOT / "build" / "simavr"
SIMAVR_LIBS = ("-lsimavr", "-lsimavrparts", "-lutil", "-lpthread", "-lm")
SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")
APT_HINT = ("install it with: sudo apt-get install --no-install-recommends simavr "
            "libsimavr-dev (or run bash tools/bootstrap.sh)")


class SimulatorError(UserError):
    """simavr is missing, or the firmware did not finish as expected."""


@dataclass
class SimResult:
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
    """Compile a C program on libsimavr with the host compiler into build/simavr/NAME-HASH
    (rebuilt when a source or a file in ``depends`` changes). Raises ``error`` (default
    :class:`SimulatorError`) with one line saying what to install."""
    error = error or SimulatorError
    cc = shutil.which("gcc") or shutil.which("cc")
    if not cc:
        raise error("no host C compiler (gcc) found; install gcc")
    if not SIMAVR_HEADER.exists():
        raise error(f"simavr headers not found; {APT_HINT}")
    sources = [Path(p) for p in sources]
    compile_cmd = [cc, "-O2", "-Wall", "-Wextra", "-Werror", "-std=gnu11", *map(str, sources)]
    # The key covers the command line (all but the output path) as well as the files, so a
    # changed flag or compiler rebuilds too.
    digest = hashlib.sha256("\0".join([*compile_cmd, *SIMAVR_LIBS]).encode() + b"\0")
    for path in [*sources, *map(Path, depends)]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    exe = BUILD_DIR / f"{name}-{digest.hexdigest()[:12]}"
    if exe.exists():
        return exe
    BUILD_DIR.mkdir(parents=True, exist_ok=True)
    tmp = exe.with_name(f"{exe.name}.{os.getpid()}.tmp")   # concurrent builds do not collide
    cmd = [*compile_cmd, "-o", str(tmp), *SIMAVR_LIBS]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise error(f"building {name} failed ({APT_HINT}):\n{' '.join(cmd)}\n"
                    f"{proc.stderr.strip()}")
    tmp.replace(exe)
    return exe


def harness() -> Path:
    """Path of the compiled runner (built on first use, rebuilt when its source changes)."""
    return build_tool("delta6_sim", [HARNESS_SOURCE])


def run(elf: Path, *, mcu: str = "atmega328p", freq: int = 16_000_000,
        max_cycles: int = 200_000_000, stop_marker: int = 0xFF,
        timeout_s: float | None = 300.0) -> SimResult:
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
        return SimResult(markers=pairs, uart=uart.read_bytes(), stderr=proc.stderr)
