"""Flashing a board in one step: the generated headers for the chosen design (and calibration
and on-chip model), PlatformIO's build and upload, then the board asked who it is. PlatformIO
is the optional ``firmware`` extra (``pip install -e '.[firmware]'``); it downloads its AVR
platforms on first use.

Each step is a function so that what cannot run here (PlatformIO needs its platforms and a board)
is still checked: the command it prepares, and the answer of a board (the virtual board in the
tests) against the hashes expected.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from delta6.core.errors import UserError

#: The PlatformIO environment of the Arduino Nano Every (firmware/platformio.ini).
DEFAULT_ENV = "nano_every"
#: Seconds a freshly flashed board may take to reset, enumerate and answer.
ANSWER_TIMEOUT = 15.0


@dataclass(frozen=True)
class Expected:
    """What the flashed board must report: the design it was generated for, and the
    calibration and on-chip model built in (hash 0 and no name: none)."""

    design_name: str
    design_hash: int
    calibration_name: str = ""
    calibration_hash: int = 0
    model_name: str = ""
    model_hash: int = 0

    def parts(self) -> list[tuple[str, str, int]]:
        """(what, name, hash) of the design, the calibration and the model."""
        return [("design", self.design_name, self.design_hash),
                ("calibration", self.calibration_name, self.calibration_hash),
                ("model", self.model_name, self.model_hash)]

    def describe(self) -> str:
        return ", ".join(_describe(what, name, h) for what, name, h in self.parts()
                         if h or what == "design")


def _describe(what: str, name: str, hash32: int) -> str:
    return f"{what} '{name}' (hash 0x{hash32:08x})" if hash32 else f"no {what}"


def reported(info) -> Expected:
    """What a board's INFO record says it carries (a device older than protocol 1.1 or 1.2
    reads as no calibration or no model)."""
    return Expected(info.design_name, info.design_hash, info.calibration_name,
                    info.calibration_hash, info.model_name, info.model_hash)


def find_pio(explicit: str | None = None) -> str:
    """The PlatformIO executable: ``explicit``, else ``pio`` next to this Python (the extra's
    install), else on PATH. One line saying how to get it when there is none."""
    if explicit:
        if shutil.which(explicit) is None:
            raise UserError(f"PlatformIO not found at {explicit}")
        return explicit
    beside = Path(sys.executable).parent / "pio"
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which("pio") or shutil.which("platformio")
    if found is None:
        raise UserError("PlatformIO (pio) is not installed: pip install -e '.[firmware]' in the "
                        "checkout, or pass --pio PATH")
    return found


def pio_command(pio: str, firmware_dir: Path, env: str, port: str) -> list[str]:
    """Build and upload ``env`` from ``firmware_dir`` to the board on ``port``."""
    return [pio, "run", "-d", str(firmware_dir), "-e", env, "-t", "upload", "--upload-port", port]


def run_pio(command: list[str]) -> None:
    """Run PlatformIO with its output on the terminal; one line when it fails."""
    try:
        proc = subprocess.run(command)
    except OSError as exc:
        raise UserError(f"cannot run {command[0]}: {exc.strerror}") from None
    if proc.returncode != 0:
        raise UserError(f"PlatformIO failed (exit status {proc.returncode}) running "
                        f"{' '.join(command[1:])}; its output is above")


def check_board(port: str, expected: Expected, *, baud: int, timeout: float = ANSWER_TIMEOUT,
                open_device=None):
    """Ask the board on ``port`` for its info record, retrying while it resets after the upload;
    raise UserError when it does not answer or reports another design. Returns the info."""
    if open_device is None:
        from delta6.link.device import Device

        def open_device():
            return Device(port, baud=baud).open()
    deadline = time.monotonic() + timeout
    last: Exception | None = None
    while True:
        try:
            with open_device() as dev:
                info = dev.info(refresh=True)
            break
        except UserError as exc:            # not back yet: the port is re-enumerating
            last = exc
            if time.monotonic() >= deadline:
                raise UserError(f"the board on {port} did not answer within {timeout:g} s after "
                                f"flashing ({last})") from None
            time.sleep(0.5)
    got = reported(info)
    wrong = [(mine, theirs) for mine, theirs in zip(expected.parts(), got.parts())
             if mine[2] != theirs[2]]
    if wrong:
        said = ", ".join(_describe(*theirs) for _, theirs in wrong)
        wanted = ", ".join(_describe(*mine) for mine, _ in wrong)
        raise UserError(f"the board on {port} reports {said}, expected {wanted}: the upload "
                        "did not take, or another board answered")
    return info
