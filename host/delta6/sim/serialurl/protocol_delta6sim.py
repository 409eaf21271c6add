"""``delta6sim://[DESIGN][?option=value&...]``: a simulated Delta6 as a pyserial port.

DESIGN is a design name from the repository's ``designs/`` folder (default ``delta6``) or,
with ``design=PATH``, any design file. Device time follows the wall clock (times ``speed``).

Options (all optional):
  rate=HZ             configured sample rate before any start (default 200)
  baud=N              the simulated UART's baud rate (default 500000); the host must use the
                      same, or it reads garbage like on a real port
  max_rate=HZ         the board's highest loop rate (default 2000)
  motion=sine|static  sine: every joint moves (default); static: a fixed pose (pose=...)
  pose=a,b,c,d,e,f    joint angles in rad for motion=static (default all 0)
  amplitude=F         sine amplitude as a fraction of the joint limit (default 0.3)
  encoder_fault=J:P   joint J (1..6) fails a read with probability P (repeat with commas)
  solver_fail=P, overrun=P   probabilities per sample
  eeprom=PATH         keep the EEPROM in a file (survives reopening, like a power cycle)
  vanish_after=S      the device disappears after S seconds (an unplugged cable)
  speed=X             device time runs X times faster than the wall clock (default 1)
  start_us=N          the device clock at power-on (test the 32-bit wrap-around)
  seed=N              random seed of motion and faults
  tx_capacity=N       bytes of the simulated transmit queue (default 256)
"""
from __future__ import annotations

import math
import threading
import time
import urllib.parse
from pathlib import Path

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from delta6.core.design import DEFAULT_DESIGN, MAX_RATE_HZ
from delta6.sim.simdevice import Motion, SimulatedDevice


def _floats(text: str, n: int, name: str) -> list[float]:
    values = [float(v) for v in text.split(",")]
    if len(values) != n:
        raise ValueError(f"{name} takes {n} comma-separated numbers")
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{name} takes finite numbers, got {text}")
    return values


def parse_url(url: str) -> dict:
    """SimulatedDevice arguments plus the handler's own (speed, vanish_after, eeprom_path)."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme.lower() != "delta6sim":
        raise SerialException(f"expected a delta6sim:// URL, got {url!r}")
    name = (parts.netloc + parts.path).strip("/")
    design = DEFAULT_DESIGN.parent / f"{name}.toml" if name else DEFAULT_DESIGN
    opts = {"design": design, "speed": 1.0, "vanish_after": None, "eeprom_path": None}
    motion, pose, amplitude, faults = "sine", [0.0] * 6, 0.3, {}
    integers = {"rate": "rate_hz", "baud": "baud", "max_rate": "max_rate_hz", "seed": "seed",
                "start_us": "start_us", "tx_capacity": "tx_capacity"}
    try:
        for key, values in urllib.parse.parse_qs(parts.query, keep_blank_values=True).items():
            value = values[-1]
            if key in integers:
                opts[integers[key]] = _within(key, int(value))
            elif key in ("solver_fail", "overrun", "speed", "vanish_after"):
                opts[key] = _within(key, float(value))
            elif key == "design":
                opts["design"] = Path(value)
            elif key == "eeprom":
                opts["eeprom_path"] = Path(value)
            elif key == "motion":
                if value not in ("sine", "static"):
                    raise ValueError("motion is sine or static")
                motion = value
            elif key == "pose":
                pose = _floats(value, 6, "pose")
            elif key == "amplitude":
                amplitude = _within(key, float(value))
            elif key == "encoder_fault":
                for item in value.split(","):
                    joint, _, p = item.partition(":")
                    if not 1 <= int(joint) <= 6:
                        raise ValueError("encoder_fault joints are 1..6")
                    faults[int(joint)] = _within("encoder_fault", float(p))
            else:
                raise ValueError(f"unknown option {key!r}")
    except ValueError as exc:
        raise SerialException(f"{url}: {exc}") from None
    if not Path(opts["design"]).exists():
        raise SerialException(f"{url}: design file {opts['design']} not found")
    eeprom = opts["eeprom_path"]
    if eeprom is not None and not eeprom.resolve().parent.is_dir():
        # Checked now: the image is written when a configuration is saved, much later.
        raise SerialException(f"{url}: the folder of eeprom={eeprom} does not exist")
    opts["encoder_faults"] = faults
    opts["_motion"] = (motion, pose, amplitude)
    return opts


class Serial(SerialBase):
    """The simulated device behind the pyserial interface. Thread-safe for one reader thread
    and one writer thread (what :class:`delta6.link.device.Device` does)."""

    def open(self):
        if self.is_open:
            raise SerialException("port is already open")
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        opts = parse_url(self.portstr)
        self._speed = opts.pop("speed")
        self._vanish_after = opts.pop("vanish_after")
        self._eeprom_path = opts.pop("eeprom_path")
        kind, pose, amplitude = opts.pop("_motion")
        design_path = opts.pop("design")
        eeprom = None
        if self._eeprom_path is not None and self._eeprom_path.exists():
            eeprom = self._eeprom_path.read_bytes()
        self._lock = threading.Lock()
        self._sim = SimulatedDevice(design_path, eeprom=eeprom, **opts)
        self._sim.motion = (Motion.static(pose) if kind == "static" else
                            Motion.sine(self._sim.design, amplitude, opts.get("seed", 0)))
        self._eeprom_writes = self._sim.core.eeprom_writes
        self._opened_at = time.monotonic()
        self.is_open = True

    def close(self):
        if self.is_open:
            self.is_open = False
            self._sim.close()
        super().close()

    def _reconfigure_port(self, force_update=False):
        pass

    # -- the simulation follows the wall clock ---------------------------------------------

    def _check(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        if self._vanish_after is not None and \
                time.monotonic() - self._opened_at >= self._vanish_after:
            raise SerialException("device disconnected (the simulated cable was unplugged)")

    def _advance(self) -> None:
        elapsed = (time.monotonic() - self._opened_at) * self._speed
        self._sim.advance_to(self._sim.start_us + elapsed * 1e6)

    def _garble(self, data: bytes) -> bytes:
        """Bytes at a baud rate other than the device's arrive as nonsense."""
        if self._baudrate == self._sim.baud:
            return data
        return bytes(b ^ 0xA5 for b in data)

    @property
    def in_waiting(self) -> int:
        with self._lock:
            self._check()
            self._advance()
            return self._sim.pending

    def read(self, size=1):
        deadline = None if self._timeout is None else time.monotonic() + self._timeout
        out = bytearray()
        while len(out) < size:
            with self._lock:
                self._check()
                self._advance()
                out += self._sim.read(size - len(out))
                period = 1.0 / (self._sim.core.rate_hz * self._speed)
            if len(out) >= size:
                break
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                break
            wait = period if deadline is None else min(period, deadline - now)
            time.sleep(max(wait, 0.0005))
        return self._garble(bytes(out))

    def write(self, data):
        data = bytes(data)
        with self._lock:
            self._check()
            self._advance()
            self._sim.write(self._garble(data))
            if self._eeprom_path is not None and self._sim.core.eeprom_writes != self._eeprom_writes:
                self._eeprom_writes = self._sim.core.eeprom_writes
                self._eeprom_path.write_bytes(self._sim.core.eeprom)
        return len(data)

    def reset_input_buffer(self):
        with self._lock:
            self._check()
            self._advance()
            self._sim.read()

    def reset_output_buffer(self):
        pass

    def flush(self):
        pass

    @property
    def simulation(self) -> SimulatedDevice:
        """The simulated device itself (tests inspect and steer it)."""
        return self._sim


#: The ranges of the URL's numbers (a rate of -5 wrapped to 65531 Hz; nan passed as a float).
_RANGES = {"rate": (1, MAX_RATE_HZ), "baud": (1, 10_000_000), "max_rate": (1, MAX_RATE_HZ),
           "seed": (0, 2**63 - 1), "start_us": (0, 2**32 - 1), "tx_capacity": (1, 1 << 20),
           "solver_fail": (0.0, 1.0), "overrun": (0.0, 1.0), "speed": (1e-6, 1e6),
           "vanish_after": (0.0, 1e9), "amplitude": (0.0, 1.0), "encoder_fault": (0.0, 1.0)}


def _within(key: str, value):
    lo, hi = _RANGES[key]
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{key}={value} is outside {lo}..{hi}")
    return value
