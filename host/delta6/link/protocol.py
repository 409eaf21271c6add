"""The Delta6 wire protocol, version 1.0: every number and layout of ``docs/protocol.md``.

The tables here (record types, commands, modes, status bits, NACK reasons, event codes,
configuration problems, the field layouts of every record, command and the EEPROM blob) are
the only copy: ``delta6 codegen --wire`` writes them into the header the firmware core includes
(``firmware/lib/delta6_core/src/generated/delta6_wire.h``), and tests fail when that header is
stale. This module packs and parses single frames; :mod:`delta6.link.decoder` and
:mod:`delta6.link.bulkdecode` split byte streams into them.
"""
from __future__ import annotations

import enum
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from delta6.core.model import ENCODER_COUNT_RAD
from delta6.link import cobs
from delta6.link.crc import crc16
from delta6.link.layout import Field, Layout

VERSION = (1, 1)

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
#: Types 0x01..0x7F are records (device to host), 0x80..0xFF commands (host to device).
FIRST_COMMAND_TYPE = 0x80
#: The device's receive buffer: command frames (COBS-encoded, delimiter excluded) longer than
#: this are discarded and counted (``rx_overflows``); it leaves room for commands up to 29
#: payload bytes, so a longer command from a newer host is answered with BAD_LENGTH.
COMMAND_BUFFER = 32


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


class ConfigProblem(enum.IntEnum):
    """Why a stored configuration was rejected at boot (the CONFIG_DEFAULTS event's argument)."""

    ERASED = 1
    BAD_CRC = 2
    BAD_VERSION = 3
    OUT_OF_RANGE = 4


CONFIG_PROBLEM_TEXT = {
    ConfigProblem.ERASED: "EEPROM erased or never saved",
    ConfigProblem.BAD_CRC: "CRC mismatch",
    ConfigProblem.BAD_VERSION: "unknown layout version",
    ConfigProblem.OUT_OF_RANGE: "value out of range",
}


def config_problem_text(code: int) -> str:
    """Why the device fell back to its defaults, in words (unknown codes by number)."""
    try:
        return CONFIG_PROBLEM_TEXT[ConfigProblem(code)]
    except ValueError:
        return f"reason {code}"


# --- layouts (little-endian; the CRC after the payload is big-endian) ---------------------

_TYPE = Field("type", "B")
_REQUEST = Field("request_id", "B")
_DATA = [_TYPE, Field("seq", "H"), Field("time_us", "I"), Field("status", "H"),
         Field("wrench", "h", 6)]

#: The payload of each record (type byte included, CRC excluded). Field names are those of
#: the record's tuple below; a minor version only appends fields.
RECORD_LAYOUTS = {
    RecordType.WRENCH: Layout("WRENCH", _DATA),
    RecordType.WRENCH_RAW: Layout("WRENCH_RAW", _DATA + [Field("counts", "H", 6)]),
    RecordType.INFO: Layout("INFO", [
        _TYPE, _REQUEST, Field("protocol", "B", 2), Field("firmware", "B", 3),
        Field("mode", "B"), Field("design_hash", "I"), Field("design_name", "s", 24),
        Field("full_scale", "f", 6), Field("lsb_mantissa", "B", 6),
        Field("lsb_exponent", "b", 6), Field("rate_hz", "H"), Field("max_rate_hz", "H"),
        Field("status", "H"), Field("streaming", "B"), Field("reserved", "B"),
        Field("baud", "I"), Field("serial_number", "I"), Field("zero_counts", "H", 6),
        Field("tare", "f", 6), Field("joint_limit_rad", "f"),
        # 1.1: the calibration the firmware applies (hash 0 and no name: none).
        Field("calibration_hash", "I"), Field("calibration_name", "s", 24)]),
    RecordType.ACK: Layout("ACK", [_TYPE, _REQUEST, Field("command", "B"), Field("value", "I")]),
    RecordType.NACK: Layout("NACK", [_TYPE, _REQUEST, Field("command", "B"),
                                     Field("reason", "B"), Field("detail", "I")]),
    RecordType.TELEMETRY: Layout("TELEMETRY", [
        _TYPE, _REQUEST, Field("time_us", "I"), Field("status", "H"), Field("samples", "I"),
        Field("overruns", "H"), Field("encoder_errors", "H", 6), Field("solver_errors", "H"),
        Field("rx_frames", "H"), Field("rx_crc_errors", "H"), Field("rx_bad_frames", "H"),
        Field("rx_overflows", "H"), Field("tx_dropped", "H"), Field("responses_dropped", "H"),
        Field("loop_time_max_us", "H"), Field("loop_time_mean_us", "H"),
        Field("temperature_centi", "h"), Field("next_seq", "H")]),
    RecordType.EVENT: Layout("EVENT", [_TYPE, Field("code", "B"), Field("arg", "I")]),
}
RECORD_SIZES = {t: layout.size for t, layout in RECORD_LAYOUTS.items()}
#: INFO as protocol 1.0 sent it (without the calibration fields), still accepted.
INFO_SIZE_1_0 = RECORD_LAYOUTS[RecordType.INFO].offsets["calibration_hash"]
_WRENCH = RECORD_LAYOUTS[RecordType.WRENCH].struct
_WRENCH_RAW = RECORD_LAYOUTS[RecordType.WRENCH_RAW].struct

#: The data records as numpy structured dtypes, for decoding many at once: one element is a
#: COBS-decoded frame, the record followed by its CRC.
DATA_FRAME_DTYPES = {t: RECORD_LAYOUTS[t].dtype([("crc", ">u2")])
                     for t in (RecordType.WRENCH, RecordType.WRENCH_RAW)}

#: Every command: type, request id, then its arguments.
COMMAND_LAYOUTS = {c: Layout(c.name, [_TYPE, _REQUEST, *args]) for c, args in {
    Command.GET_INFO: [], Command.PING: [], Command.START: [Field("rate_hz", "H")],
    Command.STOP: [], Command.SET_MODE: [Field("mode", "B")],
    Command.TARE: [Field("samples", "H")], Command.CLEAR_TARE: [], Command.SAVE_CONFIG: [],
    Command.LOAD_DEFAULTS: [], Command.SET_ZERO: [Field("zero_counts", "H", 6)],
    Command.ZERO_HERE: [Field("samples", "H")], Command.GET_TELEMETRY: [],
}.items()}
#: Argument format of each command (``struct``, after type and request id).
COMMAND_ARGS = {c: "".join(f.fmt for f in layout.fields[2:])
                for c, layout in COMMAND_LAYOUTS.items()}
COMMAND_SIZES = {c: layout.size for c, layout in COMMAND_LAYOUTS.items()}
MAX_RECORD_SIZE = max(RECORD_SIZES.values())

#: The configuration blob in the device's EEPROM (docs/protocol.md section 9), followed by
#: its CRC (most significant byte first, like frames).
CONFIG_LAYOUT = Layout("CONFIG", [
    Field("magic", "H"), Field("layout", "B"), Field("size", "B"), Field("design_hash", "I"),
    Field("rate_hz", "H"), Field("mode", "B"), Field("tare_active", "B"), Field("tare", "f", 6),
    Field("zero_counts", "H", 6)])
CONFIG_MAGIC = 0x3644           # "D6" little-endian
CONFIG_LAYOUT_VERSION = 1
CONFIG_BLOB_SIZE = CONFIG_LAYOUT.size + CRC_SIZE
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
    calibration_hash: int = 0      # 1.1; 0: the analytical model, no calibration
    calibration_name: str = ""

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


# parse_payload reads data records in WrenchRecord's field order, and the firmware writes
# both data records with one set of offsets.
if [f.name for f in RECORD_LAYOUTS[RecordType.WRENCH_RAW].fields] != ["type", *WrenchRecord._fields] \
        or not RECORD_LAYOUTS[RecordType.WRENCH_RAW].starts_with(RECORD_LAYOUTS[RecordType.WRENCH]):
    raise AssertionError("the data records are WRENCH = type + WrenchRecord's fields, "
                         "WRENCH_RAW = WRENCH + counts")

_RECORD_TUPLES = {RecordType.INFO: Info, RecordType.ACK: Ack, RecordType.NACK: Nack,
                  RecordType.TELEMETRY: Telemetry, RecordType.EVENT: Event}


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
    if kind == RecordType.INFO and INFO_SIZE_1_0 <= len(payload) < size:
        payload = bytes(payload) + bytes(size - len(payload))   # a 1.0 device: no calibration
    if len(payload) < size:
        raise ProtocolError(f"record type 0x{kind:02x} has {len(payload)} bytes, needs {size}")
    # Data records by position, twice as fast as by name (the order is checked at import):
    # type, seq, time_us, status, wrench[6], counts[6].
    if kind == RecordType.WRENCH:
        v = _WRENCH.unpack_from(payload)
        return WrenchRecord(v[1], v[2], v[3], v[4:10], None)
    if kind == RecordType.WRENCH_RAW:
        v = _WRENCH_RAW.unpack_from(payload)
        return WrenchRecord(v[1], v[2], v[3], v[4:10], v[10:16])
    fields = RECORD_LAYOUTS[kind].unpack(payload)
    del fields["type"]
    if kind == RecordType.INFO:
        del fields["reserved"]
        for key in ("design_name", "calibration_name"):
            fields[key] = fields[key].split(b"\x00", 1)[0].decode("ascii", "replace")
        fields["streaming"] = bool(fields["streaming"])
    return _RECORD_TUPLES[kind](**fields)


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
    layout = COMMAND_LAYOUTS[Command(command)]
    return frame(layout.struct.pack(command, request_id, *args))


def encode_wrench(seq: int, time_us: int, status: int, wrench, counts=None) -> bytes:
    if counts is None:
        return frame(_WRENCH.pack(RecordType.WRENCH, seq, time_us, status, *wrench))
    return frame(_WRENCH_RAW.pack(RecordType.WRENCH_RAW, seq, time_us, status, *wrench, *counts))


def encode_record(record) -> bytes:
    """The frame of an INFO, ACK, NACK, TELEMETRY or EVENT record (the tuples above)."""
    kind = next(t for t, cls in _RECORD_TUPLES.items() if isinstance(record, cls))
    fields = record._asdict()
    if kind == RecordType.INFO:
        name_field = RECORD_LAYOUTS[kind].field("design_name")
        fields.update(design_name=record.design_name.encode("ascii")[:name_field.count - 1],
                      calibration_name=record.calibration_name.encode("ascii")[
                          :name_field.count - 1],
                      streaming=int(record.streaming), reserved=0)
    return frame(RECORD_LAYOUTS[kind].pack(type=kind, **fields))


def encode_info(info: Info) -> bytes:
    return encode_record(info)


def encode_ack(request_id: int, command: int, value: int) -> bytes:
    return encode_record(Ack(request_id, command, value))


def encode_nack(request_id: int, command: int, reason: int, detail: int = 0) -> bytes:
    return encode_record(Nack(request_id, command, reason, detail))


def encode_event(code: int, arg: int) -> bytes:
    return encode_record(Event(code, arg))


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
