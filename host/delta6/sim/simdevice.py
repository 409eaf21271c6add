"""A Delta6 without hardware: the firmware's own protocol core, compiled natively, fed with
encoder counts from a synthetic motion and wrenches from the reference model.

What runs here is ``firmware/lib/delta6_core`` (command parsing, configuration and EEPROM
blob, tare, quantisation, record encoding, telemetry), the same code the board runs, behind a
stand-in board layer (``firmware/native/sim_hardware.h``) whose transmit queue drains at the
baud rate, so a rate the link cannot carry loses records exactly as on the board. The solver is
replaced by :func:`delta6.core.model.wrench` on the angles the counts encode, so every wrench the
host receives can be checked against the reference; like the board's, it gives no wrench for a
pose outside the joint box.

Users reach it as a serial port URL, ``delta6sim://`` (see :mod:`delta6.sim.serialurl`); tests use
:class:`SimulatedDevice` directly and move its clock by hand.
"""
from __future__ import annotations

import ctypes
import functools
import random
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.build import nativebuild
from delta6.core.design import DEFAULT_DESIGN, Design, load
from delta6.core.model import wrench as model_wrench
from delta6.core.spec import full_scale
from delta6.link.protocol import (
    DEFAULT_BAUD,
    TEMPERATURE_UNKNOWN,
    Mode,
    count_delta,
    counts_to_theta,
    theta_to_counts,
)
from delta6_codegen.solver_constants import limit_counts

#: Encoder counts at zero deflection of the simulated mechanism (any values do).
DEFAULT_ZERO = (1200, 5400, 9800, 14100, 300, 16000)
EEPROM_SIZE = 256

_u8p = ctypes.POINTER(ctypes.c_uint8)


@functools.cache
def native_library() -> ctypes.CDLL:
    """The device core plus its C interface (``firmware/native/delta6_sim.cpp``), built once."""
    lib = nativebuild.load_library(
        "delta6_sim", [nativebuild.FIRMWARE_NATIVE / "delta6_sim.cpp",
                       *nativebuild.core_sources()],
        [nativebuild.FIRMWARE_CORE, nativebuild.FIRMWARE_NATIVE])
    c = ctypes
    sig = {
        "d6sim_create": (c.c_void_p, [c.c_char_p, c.c_uint32, c.c_void_p, c.c_float, c.c_int16,
                                      c.c_uint32, c.c_uint16, c.c_uint16, c.c_void_p,
                                      c.c_uint32, c.c_uint16]),
        "d6sim_destroy": (None, [c.c_void_p]),
        "d6sim_begin": (None, [c.c_void_p, c.c_uint8, c.c_uint16]),
        "d6sim_set_time": (None, [c.c_void_p, c.c_uint32]),
        "d6sim_feed": (None, [c.c_void_p, c.c_char_p, c.c_uint32]),
        "d6sim_samples": (None, [c.c_void_p, c.c_uint32] + [c.c_void_p] * 7 + [c.c_int16]),
        "d6sim_pending": (c.c_uint32, [c.c_void_p]),
        "d6sim_read": (c.c_uint32, [c.c_void_p, c.c_void_p, c.c_uint32]),
        "d6sim_rate": (c.c_uint16, [c.c_void_p]),
        "d6sim_rate_changes": (c.c_uint32, [c.c_void_p]),
        "d6sim_streaming": (c.c_int, [c.c_void_p]),
        "d6sim_mode": (c.c_uint8, [c.c_void_p]),
        "d6sim_status": (c.c_uint16, [c.c_void_p]),
        "d6sim_zero_counts": (None, [c.c_void_p, c.c_void_p]),
        "d6sim_tare": (None, [c.c_void_p, c.c_void_p]),
        "d6sim_eeprom": (_u8p, [c.c_void_p]),
        "d6sim_eeprom_size": (c.c_uint32, []),
        "d6sim_eeprom_writes": (c.c_uint32, [c.c_void_p]),
        "d6sim_break_eeprom": (None, [c.c_void_p, c.c_int]),
        "d6sim_link_limit": (c.c_uint16, [c.c_void_p, c.c_uint8]),
        "d6sim_sizeof_device": (c.c_uint32, []),
        "d6sim_set_max_rate_pipeline": (None, [c.c_void_p, c.c_uint16]),
        "d6_crc16": (c.c_uint16, [c.c_char_p, c.c_uint32]),
        "d6_cobs_encode_in_place": (c.c_uint32, [c.c_void_p, c.c_uint32]),
        "d6_cobs_decode_in_place": (c.c_int32, [c.c_void_p, c.c_uint32]),
        "d6_record_size": (c.c_uint32, [c.c_uint8]),
        "d6_command_size": (c.c_uint32, [c.c_uint8]),
        "d6_encode_data": (c.c_uint32, [c.c_void_p, c.c_uint16, c.c_uint32, c.c_uint16,
                                        c.c_void_p, c.c_void_p]),
        "d6_scale": (None, [c.c_float, c.c_void_p, c.c_void_p]),
        "d6_quantize": (c.c_int16, [c.c_float, c.c_float, c.c_void_p]),
        "d6_parse_commands": (c.c_uint32, [c.c_char_p, c.c_uint32, c.c_void_p, c.c_uint32]),
        "d6_encode_config": (None, [c.c_void_p, c.c_void_p, c.c_void_p, c.c_void_p,
                                    c.c_void_p, c.c_uint32, c.c_void_p]),
    }
    for name, (restype, argtypes) in sig.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


def _ptr(array: np.ndarray) -> ctypes.c_void_p:
    return array.ctypes.data_as(ctypes.c_void_p)


class NativeCore:
    """One instance of the firmware's ``delta6::Device`` behind the simulated board layer."""

    def __init__(self, *, design_name: str, design_hash: int, full_scale, joint_limit_rad: float,
                 joint_limit_counts: int, baud: int, max_rate_hz: int, default_rate_hz: int, zero_counts,
                 serial_number: int = 0, tx_capacity: int = 256):
        self._h = None     # close() and __del__ work even if building the library fails
        self._lib = native_library()
        fs = np.ascontiguousarray(full_scale, dtype=np.float32)
        zero = np.ascontiguousarray(zero_counts, dtype=np.uint16)
        self._h = self._lib.d6sim_create(design_name.encode("ascii"), design_hash, _ptr(fs),
                                         joint_limit_rad, joint_limit_counts, baud,
                                         max_rate_hz, default_rate_hz,
                                         _ptr(zero), serial_number, tx_capacity)

    def close(self) -> None:
        if self._h:
            self._lib.d6sim_destroy(self._h)
            self._h = None

    def __del__(self):
        self.close()

    def begin(self, reset_cause: int = 0, boot_id: int = 0) -> None:
        self._lib.d6sim_begin(self._h, reset_cause, boot_id)

    def set_time(self, time_us: int) -> None:
        self._lib.d6sim_set_time(self._h, int(time_us) & 0xFFFFFFFF)

    def feed(self, data: bytes) -> None:
        self._lib.d6sim_feed(self._h, bytes(data), len(data))

    def samples(self, time_us, counts, encoder_errors, solver_ok, wrench, overrun, loop_us,
                temperature_centi: int = TEMPERATURE_UNKNOWN) -> None:
        n = len(time_us)
        arrays = [np.ascontiguousarray(np.asarray(time_us, dtype=np.int64) & 0xFFFFFFFF,
                                       dtype=np.uint32),
                  np.ascontiguousarray(counts, dtype=np.uint16).reshape(n, 6),
                  np.ascontiguousarray(encoder_errors, dtype=np.uint8),
                  np.ascontiguousarray(solver_ok, dtype=np.uint8),
                  np.ascontiguousarray(wrench, dtype=np.float32).reshape(n, 6),
                  np.ascontiguousarray(overrun, dtype=np.uint8),
                  np.ascontiguousarray(loop_us, dtype=np.uint16)]
        self._lib.d6sim_samples(self._h, n, *map(_ptr, arrays), temperature_centi)

    @property
    def pending(self) -> int:
        return self._lib.d6sim_pending(self._h)

    def read(self, max_bytes: int | None = None) -> bytes:
        n = self.pending if max_bytes is None else min(max_bytes, self.pending)
        buf = ctypes.create_string_buffer(max(n, 1))
        got = self._lib.d6sim_read(self._h, buf, n)
        return buf.raw[:got]

    @property
    def rate_hz(self) -> int:
        return self._lib.d6sim_rate(self._h)

    @property
    def rate_changes(self) -> int:
        return self._lib.d6sim_rate_changes(self._h)

    @property
    def streaming(self) -> bool:
        return bool(self._lib.d6sim_streaming(self._h))

    @property
    def mode(self) -> Mode:
        return Mode(self._lib.d6sim_mode(self._h))

    @property
    def status(self) -> int:
        return self._lib.d6sim_status(self._h)

    @property
    def zero_counts(self) -> np.ndarray:
        out = np.zeros(6, dtype=np.uint16)
        self._lib.d6sim_zero_counts(self._h, _ptr(out))
        return out

    @property
    def tare(self) -> np.ndarray:
        out = np.zeros(6, dtype=np.float32)
        self._lib.d6sim_tare(self._h, _ptr(out))
        return out

    @property
    def eeprom(self) -> bytes:
        return ctypes.string_at(self._lib.d6sim_eeprom(self._h), EEPROM_SIZE)

    @eeprom.setter
    def eeprom(self, data: bytes) -> None:
        data = bytes(data)[:EEPROM_SIZE].ljust(EEPROM_SIZE, b"\xff")
        ctypes.memmove(self._lib.d6sim_eeprom(self._h), data, EEPROM_SIZE)

    @property
    def eeprom_writes(self) -> int:
        return self._lib.d6sim_eeprom_writes(self._h)

    def break_eeprom(self, broken: bool = True) -> None:
        self._lib.d6sim_break_eeprom(self._h, int(broken))

    def set_max_rate_pipeline(self, hz: int) -> None:
        """The board's highest rate with the filter or tool frame on (0: its maximum)."""
        self._lib.d6sim_set_max_rate_pipeline(self._h, hz)

    def link_limit(self, mode: Mode) -> int:
        return self._lib.d6sim_link_limit(self._h, int(mode))


@dataclass
class Motion:
    """Joint angles over time: a static pose plus one sine per joint (rad, Hz)."""

    pose: np.ndarray
    amplitude: np.ndarray
    frequency: np.ndarray
    phase: np.ndarray

    @classmethod
    def sine(cls, design: Design, fraction: float = 0.3, seed: int = 0) -> "Motion":
        """Smooth motion inside the joint box: amplitude ``fraction`` of the joint limit."""
        rng = np.random.default_rng(seed)
        return cls(pose=np.zeros(6), amplitude=np.full(6, fraction * design.joint_limit_rad),
                   frequency=rng.uniform(0.2, 2.0, 6), phase=rng.uniform(0, 2 * np.pi, 6))

    @classmethod
    def static(cls, pose) -> "Motion":
        z = np.zeros(6)
        return cls(pose=np.asarray(pose, dtype=float).reshape(6), amplitude=z, frequency=z,
                   phase=z)

    def angles(self, t_s: np.ndarray) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)[:, None]
        return self.pose + self.amplitude * np.sin(2 * np.pi * self.frequency * t + self.phase)


class SimulatedDevice:
    """The firmware core plus a plant: call :meth:`advance` to let device time pass (samples
    are taken at the device's current rate), :meth:`write` to send it bytes, :meth:`read` to
    collect what it sent.

    Faults: ``encoder_faults`` maps a joint (1..6) to the probability that its read fails in a
    sample; ``solver_fail`` and ``overrun`` are probabilities per sample.
    """

    def __init__(self, design: Design | str | Path | None = None, *, rate_hz: int = 200,
                 baud: int = DEFAULT_BAUD, max_rate_hz: int = 2000, motion: Motion | None = None,
                 zero_counts=DEFAULT_ZERO, eeprom: bytes | None = None, tx_capacity: int = 256,
                 encoder_faults: dict | None = None, solver_fail: float = 0.0,
                 overrun: float = 0.0, loop_time_us: int = 600,
                 temperature_c: float | None = None, start_us: int = 0, seed: int = 0,
                 serial_number: int = 0xD6000001, reset_cause: int = 0,
                 boot_id: int | None = None):
        if design is None or isinstance(design, (str, Path)):
            design = load(design or DEFAULT_DESIGN)
        self.design = design
        self.baud = baud
        self.full_scale = full_scale(design)
        self.motion = motion or Motion.sine(design, seed=seed)
        self.mech_zero = np.asarray(zero_counts, dtype=np.int64)
        self.encoder_faults = dict(encoder_faults or {})
        self.solver_fail = solver_fail
        self.overrun = overrun
        self.loop_time_us = loop_time_us
        self.temperature_centi = (TEMPERATURE_UNKNOWN if temperature_c is None
                                  else int(round(temperature_c * 100)))
        self._rng = np.random.default_rng(seed + 1)
        self.limit_counts = limit_counts(design)
        self.core = NativeCore(design_name=design.name, design_hash=design.hash32(),
                               full_scale=self.full_scale,
                               joint_limit_rad=design.joint_limit_rad,
                               joint_limit_counts=self.limit_counts, baud=baud,
                               max_rate_hz=max_rate_hz, default_rate_hz=rate_hz,
                               zero_counts=zero_counts, serial_number=serial_number,
                               tx_capacity=tx_capacity)
        if eeprom is not None:
            self.core.eeprom = eeprom
        self.start_us = start_us
        self.time_us = float(start_us)       # device clock (unwrapped)
        self._next_sample_us = float(start_us)
        self.samples_taken = 0
        self.core.set_time(start_us)
        # Each simulated power-on is a boot session of its own, as on a board (random: the
        # board's counter starts from whatever its RAM held).
        self.boot_id = random.SystemRandom().randrange(65536) if boot_id is None else boot_id
        self.core.begin(reset_cause, self.boot_id)

    def close(self) -> None:
        self.core.close()

    # -- the link --------------------------------------------------------------------------

    def write(self, data: bytes) -> None:
        self.core.set_time(int(self.time_us))
        self.core.feed(data)

    def read(self, max_bytes: int | None = None) -> bytes:
        return self.core.read(max_bytes)

    @property
    def pending(self) -> int:
        return self.core.pending

    # -- time ------------------------------------------------------------------------------

    def advance(self, seconds: float, max_batch: int = 1000) -> int:
        """Let ``seconds`` of device time pass; returns the number of samples taken."""
        return self.advance_to(self.time_us + seconds * 1e6, max_batch)

    def advance_to(self, time_us: float, max_batch: int = 1000) -> int:
        taken = 0
        while self._next_sample_us <= time_us:
            period = 1e6 / self.core.rate_hz          # the rate may change between batches
            n = min(max_batch, int((time_us - self._next_sample_us) // period) + 1)
            times = self._next_sample_us + period * np.arange(n)
            self._take(np.floor(times).astype(np.int64))
            self._next_sample_us += period * n
            taken += n
        self.time_us = max(self.time_us, time_us)
        self.core.set_time(int(self.time_us))
        return taken

    def true_angles(self, time_us) -> np.ndarray:
        return self.motion.angles((np.asarray(time_us, dtype=float) - self.start_us) * 1e-6)

    def counts_at(self, time_us) -> np.ndarray:
        """What the encoders read: the angle in whole counts from the mechanical zero."""
        return theta_to_counts(self.true_angles(time_us), self.mech_zero).astype(np.int64)

    def _take(self, times: np.ndarray) -> None:
        n = len(times)
        counts = self.counts_at(times)
        errors = np.zeros(n, dtype=np.uint8)
        for joint, probability in self.encoder_faults.items():
            errors |= ((self._rng.random(n) < probability) << (joint - 1)).astype(np.uint8)
        counts = np.where((errors[:, None] >> np.arange(6)) & 1, 0, counts)
        # The application: angles from the device's current zero counts, then the solver.
        theta = counts_to_theta(counts, self.core.zero_counts)
        wrench = model_wrench(self.design, theta).astype(np.float32)
        # The board's solver refuses a pose outside the joint box (no wrench, SOLVER_ERROR);
        # the model would extrapolate.
        in_box = (np.abs(count_delta(counts, self.core.zero_counts))
                  <= self.limit_counts).all(axis=1)
        solver_ok = np.isfinite(wrench).all(axis=1) & (errors == 0) & in_box
        if self.solver_fail:
            solver_ok &= self._rng.random(n) >= self.solver_fail
        overrun = self._rng.random(n) < self.overrun if self.overrun else np.zeros(n, bool)
        self.core.samples(times, counts, errors, solver_ok, wrench, overrun,
                          np.full(n, self.loop_time_us), self.temperature_centi)
        self.samples_taken += n
