"""What the device subcommands share: the --port options, opening the device, display helpers."""
from __future__ import annotations

import argparse
import math
import re
import sys
import time

import numpy as np

from delta6.core.model import AXES  # noqa: F401 - the axis names the subcommands print
from delta6.link.device import DEFAULT_BAUD, Device, SampleBlock, SampleTimeout
from delta6.link.protocol import ENCODER_MASK, Info, Mode, Status

#: Status bits that inform rather than warn: left out of the short display.
QUIET_FLAGS = Status.TARE_ACTIVE | Status.CONFIG_DEFAULTS | Status.STREAM_CHANGED
#: Status bits that flag a sample as faulty or doubtful (counted as "flagged").
FAULT_FLAGS = (ENCODER_MASK | Status.OVERRANGE | Status.JOINT_LIMIT | Status.SOLVER_ERROR
               | Status.WRENCH_INVALID | Status.LOOP_OVERRUN | Status.TX_OVERFLOW)
#: How often a streaming loop looks for a stop request, s.
POLL_S = 0.1


def number(option: str, kind: type = float, low: float | None = None,
           high: float | None = None, low_open: bool = False):
    """An argparse type: a number of ``kind`` within [low, high] (``low_open``: above low),
    rejected with one line naming the option."""
    def convert(text: str):
        try:
            value = kind(text)
        except ValueError:
            noun = "a whole number" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"{option} takes {noun}, got {text!r}") from None
        if not math.isfinite(value):   # nan passes every comparison below
            raise argparse.ArgumentTypeError(f"{option} takes a finite number, got {text}")
        if low is not None and (value <= low if low_open else value < low):
            raise argparse.ArgumentTypeError(
                f"{option} must be {'positive' if low == 0 and low_open else f'at least {low}'}, "
                f"got {text}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"{option} must be at most {high}, got {text}")
        return value
    return convert


_FRAME_ID = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_./-]{0,63}")


def frame_id(text: str) -> str:
    """An argparse type: a ROS frame id (letters, digits, '_', '.', '/', '-'; not starting with
    '/', as tf2 wants; at most 64 characters). An empty one made messages no viewer places."""
    if not _FRAME_ID.fullmatch(text):
        raise argparse.ArgumentTypeError(
            f"--frame-id takes a frame name such as delta6_e (letters, digits, _ . / -, not "
            f"starting with /), got {text!r}")
    return text


def add_port_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True, metavar="P",
                        help="serial port (/dev/ttyACM0, COM3) or pyserial URL "
                             "(delta6sim:// for the simulated device, socket://host:port)")
    parser.add_argument("--baud", type=number("--baud", int, 1), default=DEFAULT_BAUD,
                        help=f"baud rate of the board's firmware (default {DEFAULT_BAUD})")
    parser.add_argument("--timeout", type=number("--timeout", low=0, low_open=True), default=0.5,
                        metavar="S",
                        help="seconds to wait for each answer (default 0.5; retried twice)")


def add_stream_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--rate", type=number("--rate", int, 1, 65535), metavar="HZ",
                        help="sample rate (default: the device's configured rate)")
    parser.add_argument("--raw", action="store_true",
                        help="also stream the six raw encoder counts (the theta_e columns)")


def open_device(args: argparse.Namespace, **kwargs) -> Device:
    return Device(args.port, baud=args.baud, timeout=args.timeout, exclusive=True,
                  **kwargs).open()


def next_block(dev: Device, stop, patience: float | None = None) -> SampleBlock | None:
    """The next samples, or None once ``stop`` is set (checked every :data:`POLL_S`);
    SampleTimeout after ``patience`` s without a sample (default: 20 periods, at least 1 s),
    and the device's failure (PortLost) as soon as it happens."""
    if patience is None:
        rate = dev.info().rate_hz or 1
        patience = max(1.0, 20.0 / rate)
    deadline = time.monotonic() + patience
    before = _boots(dev)
    while not stop.is_set():
        try:
            return dev.read_block(timeout=min(POLL_S, max(deadline - time.monotonic(), 0.0)))
        except SampleTimeout:
            if time.monotonic() >= deadline:
                why = ("the device restarted meanwhile and boots idle: start it again"
                       if _boots(dev) > before else "did the device stop streaming?")
                raise SampleTimeout(f"no sample from {dev.port} for {patience:g} s "
                                    f"({why})") from None
    return None


def _boots(dev: Device) -> int:
    """How many restarts the device has shown (BOOT events, new boot ids)."""
    h = dev.health
    return h.device_resets + h.restarts


def flagged(status) -> int:
    """How many of the samples carry a fault flag (FAULT_FLAGS)."""
    return int(np.count_nonzero(np.asarray(status, dtype=np.int64) & int(FAULT_FLAGS)))


def start_stream(dev: Device, args: argparse.Namespace) -> int:
    dev.set_mode(Mode.WRENCH_RAW if args.raw else Mode.WRENCH)
    return dev.start(args.rate)


def flag_names(status: int, quiet: int = QUIET_FLAGS) -> str:
    """Status bits as short names, without the ``quiet`` ones ('ok' when none is left)."""
    names = [f.name.lower() for f in Status if f & status and not f & quiet]
    return ",".join(names) if names else "ok"


def log_meta(info: Info, port: str, command: str) -> dict:
    """The header lines of a device log (docs/protocol.md, "Logs"). The wrench of a device log
    is the device's own model output, not a reference sensor's (``wrench_source``)."""
    return {
        "design": info.design_name, "design_hash": f"0x{info.design_hash:08x}",
        "source": f"{command} {port}", "wrench_source": "device",
        "firmware": info.firmware_version,
        "protocol": info.protocol_version, "serial_number": f"0x{info.serial_number:08x}",
        "baud": info.baud, "mode": Mode(info.mode).name.lower(),
        "lsb": " ".join(f"{v:g}" for v in info.lsb),
        "zero_counts": " ".join(map(str, info.zero_counts)),
        "tare": " ".join(f"{v:.9g}" for v in info.tare),
        "rate_hz": info.rate_hz,
        # The calibration the board applies (docs/calibration.md), when there is one: a host
        # refuses to evaluate the log against another.
        **({"calibration": info.calibration_name,
            "calibration_hash": f"0x{info.calibration_hash:08x}"}
           if info.calibration_hash else {}),
        # The on-chip residual model the board runs over that (docs/ondevice-model.md).
        **({"model": info.model_name, "model_hash": f"0x{info.model_hash:08x}"}
           if info.model_hash else {}),
    }


class Progress:
    """One status line on a terminal (rewritten in place), plain lines otherwise."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.shown = False
        self._width = 0

    def show(self, text: str) -> None:
        if self.tty:   # pad to the previous line's width so nothing of it remains
            self.stream.write("\r" + text.ljust(self._width))
            self._width = len(text)
        else:
            self.stream.write(text + "\n")
        self.stream.flush()
        self.shown = True

    def end(self) -> None:
        if self.tty and self.shown:
            self.stream.write("\n")
            self.stream.flush()
        self.shown = False
