"""The Delta6 wire protocol, version 1.0: every number and layout of ``docs/protocol.md``.

The firmware's copy is ``firmware/lib/delta6_core/src/delta6_protocol.h``; the tests build the
C++ natively and check both against each other byte for byte. This module packs and parses
single frames; :mod:`delta6.link.decoder` and :mod:`delta6.link.bulkdecode` split byte streams into them.
"""
from __future__ import annotations

import enum
import struct
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from delta6.core.model import ENCODER_COUNT_RAD
from delta6.link import cobs
from delta6.link.crc import crc16

VERSION = (1, 0)

#: The recommended UART rate (docs/protocol.md, "Baud rate"): exact on 16 MHz AVRs, carries
#: 1 kHz of wrench records at half load.
DEFAULT_BAUD = 500_000
#: Frame bytes on the wire beyond the payload: CRC (2), COBS code (1), delimiter (1).
FRAME_OVERHEAD = 4
CRC_SIZE = 2
COUNTS_PER_TURN = 16384
COUNT_RAD = ENCODER_COUNT_RAD
#: Raw counts of a sample that carried none (wrench-only mode): never a real 14-bit count.
NO_COUNTS = -1
INVALID_VALUE = -32768
MAX_VALUE = 32767
TEMPERATURE_UNKNOWN = 0x7FFF
BITS_PER_BYTE = 10           # UART: start bit, 8 data bits, stop bit
#: Data records may fill 90 % of the link (a fraction: the firmware computes in integers).
LINK_BUDGET = Fraction(9, 10)


class RecordType(enum.IntEnum):
    WRENCH = 0x01
    WRENCH_RAW = 0x02
    INFO = 0x03
    ACK = 0x04
    NACK = 0x05
    TELEMETRY = 0x06
    EVENT = 0x07


class Command(enum.IntEnum):
    GET_INFO = 0x80
    PING = 0x81
    START = 0x82
    STOP = 0x83
    SET_MODE = 0x84
    TARE = 0x85
    CLEAR_TARE = 0x86
    SAVE_CONFIG = 0x87
    LOAD_DEFAULTS = 0x88
    SET_ZERO = 0x89
    ZERO_HERE = 0x8A
    GET_TELEMETRY = 0x8B


class Mode(enum.IntEnum):
    WRENCH = 1
    WRENCH_RAW = 2


class Status(enum.IntFlag):
    ENCODER1 = 1 << 0
    ENCODER2 = 1 << 1
    ENCODER3 = 1 << 2
    ENCODER4 = 1 << 3
    ENCODER5 = 1 << 4
    ENCODER6 = 1 << 5
    OVERRANGE = 1 << 6
    JOINT_LIMIT = 1 << 7
    SOLVER_ERROR = 1 << 8
    WRENCH_INVALID = 1 << 9
    LOOP_OVERRUN = 1 << 10
    TX_OVERFLOW = 1 << 11
    TARE_ACTIVE = 1 << 12
    TARE_BUSY = 1 << 13
    CONFIG_DEFAULTS = 1 << 14


ENCODER_MASK = 0x3F


class NackReason(enum.IntEnum):
    UNKNOWN_COMMAND = 1
    BAD_LENGTH = 2
    BAD_ARGUMENT = 3
    RATE_TOO_HIGH = 4
    LINK_TOO_SLOW = 5
    BUSY = 6
    FAULT_DURING_AVERAGING = 7
    EEPROM_FAILED = 8


NACK_TEXT = {
    NackReason.UNKNOWN_COMMAND: "the device does not know this command (older firmware?)",
    NackReason.BAD_LENGTH: "wrong command length (expected {detail} bytes)",
    NackReason.BAD_ARGUMENT: "invalid argument ({detail})",
    NackReason.RATE_TOO_HIGH: "rate above the board's maximum of {detail} Hz",
    NackReason.LINK_TOO_SLOW: "the serial link carries at most {detail} Hz in this mode "
                              "(raise the baud rate or lower the rate)",
    NackReason.BUSY: "a tare or zero capture is still running",
    NackReason.FAULT_DURING_AVERAGING: "a sample was flagged while averaging "
                                       "(status {detail:#06x}); nothing was changed",
    NackReason.EEPROM_FAILED: "the EEPROM did not read back what was written (byte {detail})",
}


class EventCode(enum.IntEnum):
    BOOT = 1
    CONFIG_DEFAULTS = 2


CONFIG_PROBLEM_TEXT = {1: "EEPROM erased or never saved", 2: "CRC mismatch",
                       3: "unknown layout version", 4: "value out of range"}

# --- layouts (little-endian; the CRC after the payload is big-endian) ---------------------

_WRENCH = struct.Struct("<BHIH6h")
_WRENCH_RAW = struct.Struct("<BHIH6h6H")
_INFO = struct.Struct("<BB2B3BBI24s6f6B6bHHHBBII6H6ff")
_ACK = struct.Struct("<BBBI")
_NACK = struct.Struct("<BBBBI")
_TELEMETRY = struct.Struct("<BBIHIH6HHHHHHHHHHhH")
_EVENT = struct.Struct("<BBI")

RECORD_SIZES = {
    RecordType.WRENCH: _WRENCH.size, RecordType.WRENCH_RAW: _WRENCH_RAW.size,
    RecordType.INFO: _INFO.size, RecordType.ACK: _ACK.size, RecordType.NACK: _NACK.size,
    RecordType.TELEMETRY: _TELEMETRY.size, RecordType.EVENT: _EVENT.size,
}

#: The data records as numpy structured dtypes, for decoding many at once: one element is a
#: COBS-decoded frame, the record (the struct layouts above) followed by its CRC.
_DATA_FIELDS = [("type", "u1"), ("seq", "<u2"), ("time", "<u4"), ("status", "<u2"),
                ("wrench", "<i2", 6)]
DATA_FRAME_DTYPES = {
    RecordType.WRENCH: np.dtype(_DATA_FIELDS + [("crc", ">u2")]),
    RecordType.WRENCH_RAW: np.dtype(_DATA_FIELDS + [("counts", "<u2", 6), ("crc", ">u2")]),
}
for _kind, _dtype in DATA_FRAME_DTYPES.items():
    if _dtype.itemsize != RECORD_SIZES[_kind] + CRC_SIZE:   # the two layouts must agree
        raise AssertionError(f"{_kind.name}: dtype of {_dtype.itemsize} bytes, struct of "
                             f"{RECORD_SIZES[_kind]} + CRC")

#: Argument layout of each command (after type and request id).
COMMAND_ARGS = {
    Command.GET_INFO: "", Command.PING: "", Command.START: "H", Command.STOP: "",
    Command.SET_MODE: "B", Command.TARE: "H", Command.CLEAR_TARE: "", Command.SAVE_CONFIG: "",
    Command.LOAD_DEFAULTS: "", Command.SET_ZERO: "6H", Command.ZERO_HERE: "H",
    Command.GET_TELEMETRY: "",
}
COMMAND_SIZES = {c: 2 + struct.calcsize("<" + a) for c, a in COMMAND_ARGS.items()}
MAX_RECORD_SIZE = max(RECORD_SIZES.values())
#: Encoded length (no delimiter) of each record type: payload + CRC + one COBS code byte.
ENCODED_SIZES = {t: s + 3 for t, s in RECORD_SIZES.items()}


def wire_bytes(record_type: RecordType) -> int:
    """Bytes one record takes on the wire, delimiter included."""
    return RECORD_SIZES[record_type] + FRAME_OVERHEAD


def data_record_type(mode: Mode | int) -> RecordType:
    return RecordType.WRENCH_RAW if int(mode) == Mode.WRENCH_RAW else RecordType.WRENCH


def max_rate_for_link(baud: int, mode: Mode | int = Mode.WRENCH, budget: float = 1.0) -> float:
    """Highest sample rate whose data records fit ``budget`` of a UART link at ``baud``."""
    return budget * baud / (BITS_PER_BYTE * wire_bytes(data_record_type(mode)))


def link_rate_limit(baud: int, mode: Mode | int) -> int:
    """The device's own limit (integer arithmetic as in the firmware): 90 % of the link."""
    if baud == 0:
        return 0xFFFF
    # Budget bytes per second, baud / 100 * 9 as the firmware divides (first, so that no
    # product overflows 32 bits): BITS_PER_BYTE x the budget's denominator is the 100.
    budget = baud // (BITS_PER_BYTE * LINK_BUDGET.denominator) * LINK_BUDGET.numerator
    return min(0xFFFF, budget // wire_bytes(data_record_type(mode)))


# --- records ----------------------------------------------------------------------------

class WrenchRecord(NamedTuple):
    seq: int
    time_us: int
    status: int
    wrench: tuple          # six int16 counts of the LSB
    counts: tuple | None   # six raw encoder counts (WRENCH_RAW only)


class Info(NamedTuple):
    request_id: int
    protocol: tuple
    firmware: tuple
    mode: int
    design_hash: int
    design_name: str
    full_scale: tuple
    lsb_mantissa: tuple
    lsb_exponent: tuple
    rate_hz: int
    max_rate_hz: int
    status: int
    streaming: bool
    baud: int
    serial_number: int
    zero_counts: tuple
    tare: tuple
    joint_limit_rad: float

    @property
    def lsb(self) -> np.ndarray:
        """Wrench units (N, N*m) per count, per axis: mantissa x 10^exponent, exactly."""
        return np.array([lsb_value(m, e) for m, e in zip(self.lsb_mantissa, self.lsb_exponent)])

    @property
    def firmware_version(self) -> str:
        return ".".join(map(str, self.firmware))

    @property
    def protocol_version(self) -> str:
        return ".".join(map(str, self.protocol))


class Ack(NamedTuple):
    request_id: int
    command: int
    value: int


class Nack(NamedTuple):
    request_id: int
    command: int
    reason: int
    detail: int

    def text(self) -> str:
        try:
            reason = NackReason(self.reason)
        except ValueError:
            return f"rejected with unknown reason {self.reason} (detail {self.detail})"
        return NACK_TEXT[reason].format(detail=self.detail)


class Telemetry(NamedTuple):
    request_id: int
    time_us: int
    status: int
    samples: int
    overruns: int
    encoder_errors: tuple
    solver_errors: int
    rx_frames: int
    rx_crc_errors: int
    rx_bad_frames: int
    rx_overflows: int
    tx_dropped: int
    responses_dropped: int
    loop_time_max_us: int
    loop_time_mean_us: int
    temperature_centi: int
    next_seq: int

    @property
    def temperature_c(self) -> float | None:
        return None if self.temperature_centi == TEMPERATURE_UNKNOWN else self.temperature_centi / 100


class Event(NamedTuple):
    code: int
    arg: int


class ProtocolError(ValueError):
    """A frame that is not a valid record: the message says why."""


def parse_payload(payload: bytes):
    """A record from a decoded, CRC-checked payload (CRC bytes removed).

    Longer payloads than version 1.0 defines are accepted and their known prefix parsed (newer
    minor versions only append fields); shorter ones and unknown types raise ProtocolError."""
    if not payload:
        raise ProtocolError("empty frame")
    kind = payload[0]
    size = RECORD_SIZES.get(kind)
    if size is None:
        raise ProtocolError(f"unknown record type 0x{kind:02x}")
    if len(payload) < size:
        raise ProtocolError(f"record type 0x{kind:02x} has {len(payload)} bytes, needs {size}")
    if kind == RecordType.WRENCH:
        v = _WRENCH.unpack_from(payload)
        return WrenchRecord(v[1], v[2], v[3], v[4:10], None)
    if kind == RecordType.WRENCH_RAW:
        v = _WRENCH_RAW.unpack_from(payload)
        return WrenchRecord(v[1], v[2], v[3], v[4:10], v[10:16])
    if kind == RecordType.INFO:
        v = _INFO.unpack_from(payload)
        name = v[9].split(b"\x00", 1)[0].decode("ascii", "replace")
        return Info(request_id=v[1], protocol=v[2:4], firmware=v[4:7], mode=v[7],
                    design_hash=v[8], design_name=name, full_scale=v[10:16],
                    lsb_mantissa=v[16:22], lsb_exponent=v[22:28], rate_hz=v[28],
                    max_rate_hz=v[29], status=v[30], streaming=bool(v[31]), baud=v[33],
                    serial_number=v[34], zero_counts=v[35:41], tare=v[41:47],
                    joint_limit_rad=v[47])
    if kind == RecordType.ACK:
        return Ack(*_ACK.unpack_from(payload)[1:])
    if kind == RecordType.NACK:
        return Nack(*_NACK.unpack_from(payload)[1:])
    if kind == RecordType.TELEMETRY:
        v = _TELEMETRY.unpack_from(payload)
        return Telemetry(v[1], v[2], v[3], v[4], v[5], v[6:12], *v[12:])
    return Event(*_EVENT.unpack_from(payload)[1:])


def frame(payload: bytes) -> bytes:
    """A complete frame: COBS(payload + CRC big-endian) + 0x00."""
    return cobs.encode(payload + crc16(payload).to_bytes(2, "big")) + b"\x00"


def unframe(encoded: bytes) -> bytes | None:
    """The payload of one encoded frame (delimiter removed), or None if COBS or CRC fail."""
    decoded = cobs.decode(encoded)
    return None if decoded is None else checked_payload(decoded)


def checked_payload(decoded: bytes) -> bytes | None:
    """The payload of a COBS-decoded frame (payload + CRC), or None if the CRC fails."""
    if len(decoded) < CRC_SIZE + 1 or crc16(decoded) != 0:
        return None
    return decoded[:-CRC_SIZE]


# --- encoders (commands for the host; records for tests, captures and benchmarks) -------

def encode_command(command: Command, request_id: int, *args) -> bytes:
    fmt = "<BB" + COMMAND_ARGS[Command(command)]
    return frame(struct.pack(fmt, command, request_id, *args))


def encode_wrench(seq: int, time_us: int, status: int, wrench, counts=None) -> bytes:
    if counts is None:
        return frame(_WRENCH.pack(RecordType.WRENCH, seq, time_us, status, *wrench))
    return frame(_WRENCH_RAW.pack(RecordType.WRENCH_RAW, seq, time_us, status, *wrench, *counts))


def encode_info(info: Info) -> bytes:
    name = info.design_name.encode("ascii")[:23]
    return frame(_INFO.pack(RecordType.INFO, info.request_id, *info.protocol, *info.firmware,
                            info.mode, info.design_hash, name, *info.full_scale,
                            *info.lsb_mantissa, *info.lsb_exponent, info.rate_hz,
                            info.max_rate_hz, info.status, int(info.streaming), 0, info.baud,
                            info.serial_number, *info.zero_counts, *info.tare,
                            info.joint_limit_rad))


def encode_ack(request_id: int, command: int, value: int) -> bytes:
    return frame(_ACK.pack(RecordType.ACK, request_id, command, value))


def encode_nack(request_id: int, command: int, reason: int, detail: int = 0) -> bytes:
    return frame(_NACK.pack(RecordType.NACK, request_id, command, reason, detail))


def encode_event(code: int, arg: int) -> bytes:
    return frame(_EVENT.pack(RecordType.EVENT, code, arg))


def encode_telemetry(t: Telemetry) -> bytes:
    return frame(_TELEMETRY.pack(RecordType.TELEMETRY, t.request_id, t.time_us, t.status,
                                 t.samples, t.overruns, *t.encoder_errors, *t[6:]))


def lsb_value(mantissa: int, exponent: int) -> float:
    """An info record's scale field as the exact decimal step, the nearest double (1e-3, not
    float32's 0.0010000000475), so logged values print as the decimals they are."""
    return float(f"{mantissa}e{exponent}")


# --- angles ------------------------------------------------------------------------------

def count_delta(counts, zero) -> np.ndarray:
    """Signed distance of a count from its zero on the 14-bit circle, -8192..8191."""
    d = (np.asarray(counts, dtype=np.int64) - np.asarray(zero, dtype=np.int64)) % COUNTS_PER_TURN
    return np.where(d >= COUNTS_PER_TURN // 2, d - COUNTS_PER_TURN, d)


def counts_to_theta(counts, zero) -> np.ndarray:
    """Encoder angles theta_e (rad) from raw counts and the device's zero counts."""
    return count_delta(counts, zero) * COUNT_RAD


def theta_to_counts(theta, zero=0) -> np.ndarray:
    """Encoder angles (rad) -> the raw 14-bit counts an encoder reports (uint16), given the
    counts at zero deflection: the inverse of :func:`counts_to_theta` to the nearest count."""
    steps = np.round(np.asarray(theta, dtype=float) / COUNT_RAD).astype(np.int64)
    return np.mod(steps + np.asarray(zero, dtype=np.int64), COUNTS_PER_TURN).astype(np.uint16)


def valid_counts(counts, shape: tuple | None = (6,)) -> bool:
    """Whether ``counts`` are raw encoder counts, 0..16383, of ``shape`` (None: any)."""
    counts = np.asarray(counts)
    if shape is not None and counts.shape != tuple(shape):
        return False
    return bool(np.all((counts >= 0) & (counts < COUNTS_PER_TURN)))


# --- data records as values ----------------------------------------------------------------

def raw_counts(rows) -> np.ndarray:
    """(N, 6) int64 raw counts from N records' ``counts`` (None: :data:`NO_COUNTS`)."""
    return np.array([c if c is not None else (NO_COUNTS,) * 6 for c in rows], dtype=np.int64)


def wrench_values(wrench_counts, status, lsb) -> np.ndarray:
    """(N, 6) wrench in N and N*m: counts x LSB per axis; NaN where a sample had no wrench
    (WRENCH_INVALID set) or an axis holds INVALID_VALUE."""
    wrench_counts = np.asarray(wrench_counts)
    invalid = ((np.asarray(status) & Status.WRENCH_INVALID) != 0)[:, None] | (
        wrench_counts == INVALID_VALUE)
    return np.where(invalid, np.nan, wrench_counts * np.asarray(lsb, dtype=float))


def theta_values(counts, status, zero) -> np.ndarray:
    """(N, 6) encoder angles (rad) from raw counts; NaN where a sample sent no counts
    (:data:`NO_COUNTS`) or its status flags that encoder as failed."""
    counts = np.asarray(counts)
    failed = ((np.asarray(status)[:, None] >> np.arange(6)) & 1) != 0
    return np.where(failed | (counts < 0), np.nan, counts_to_theta(counts, zero))
