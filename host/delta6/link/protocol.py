"""The Delta6 wire protocol, version 1.3: every number and layout of ``docs/protocol.md``.

The tables here (record types, commands, modes, status bits, NACK reasons, event codes,
configuration problems, the field layouts of every record, command and the EEPROM blob) are
the only copy: ``delta6 codegen --wire`` writes them into the header the firmware core includes
(``firmware/lib/delta6_core/src/generated/delta6_wire.h``), and tests fail when that header is
stale. This module packs and parses single frames; :mod:`delta6.link.decoder` and
:mod:`delta6.link.bulkdecode` split byte streams into them.
"""
from __future__ import annotations

import enum
import functools
import math
import struct
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from delta6.core.design import MAX_NAME_CHARS
from delta6.core.model import ENCODER_COUNT_RAD, ENCODER_COUNTS_PER_TURN
from delta6.link import cobs
from delta6.link.crc import crc16
from delta6.link.layout import Field, Layout

VERSION = (1, 3)

#: The recommended UART rate (docs/protocol.md section 1, "Link"): exact on 16 MHz AVRs, carries
#: 1 kHz of wrench records at half load.
DEFAULT_BAUD = 500_000
#: Frame bytes on the wire beyond the payload: CRC (2), COBS code (1), delimiter (1).
FRAME_OVERHEAD = 4
CRC_SIZE = 2
COUNTS_PER_TURN = ENCODER_COUNTS_PER_TURN
COUNT_RAD = ENCODER_COUNT_RAD
#: Raw counts of a sample that carried none (wrench-only mode): never a real 14-bit count.
NO_COUNTS = -1
INVALID_VALUE = -32768
MAX_VALUE = 32767
#: The tool frames a device accepts (SET_TOOL): a tool point within 1 m of {E}'s origin per
#: axis (a longer lever has no use on this sensor), angles within one turn either way.
TOOL_MAX_TRANSLATION_M = 1.0
TOOL_MAX_ANGLE_RAD = 2 * math.pi
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


@enum.unique
class RecordType(enum.IntEnum):
    WRENCH = 0x01
    WRENCH_RAW = 0x02
    INFO = 0x03
    ACK = 0x04
    NACK = 0x05
    TELEMETRY = 0x06
    EVENT = 0x07


# Every table is @enum.unique: two branches taking the same code or bit fail at import,
# never alias silently.
@enum.unique
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
    ABORT = 0x8C           # 1.1
    SET_FILTER = 0x8D      # 1.3
    SET_TOOL = 0x8E        # 1.3
    SET_LIMITS = 0x8F      # 1.3


#: The protocol minor version that introduced each command newer than 1.0: a host sends it
#: only to a device of that minor version or later.
COMMAND_SINCE = {Command.ABORT: (1, 1), Command.SET_FILTER: (1, 3), Command.SET_TOOL: (1, 3),
                 Command.SET_LIMITS: (1, 3)}


@enum.unique
class Mode(enum.IntEnum):
    WRENCH = 1
    WRENCH_RAW = 2


@enum.unique
class Status(enum.IntFlag):
    ENCODER1 = 1 << 0
    ENCODER2 = 1 << 1
    ENCODER3 = 1 << 2
    ENCODER4 = 1 << 3
    ENCODER5 = 1 << 4
    ENCODER6 = 1 << 5
    # An axis is outside its overload limit (SET_LIMITS, 1.3) or outside the wire's range
    # (clipped): the two share this bit, no other is free.
    OVERRANGE = 1 << 6
    JOINT_LIMIT = 1 << 7
    SOLVER_ERROR = 1 << 8
    WRENCH_INVALID = 1 << 9
    LOOP_OVERRUN = 1 << 10
    TX_OVERFLOW = 1 << 11
    TARE_ACTIVE = 1 << 12
    TARE_BUSY = 1 << 13
    CONFIG_DEFAULTS = 1 << 14
    STREAM_CHANGED = 1 << 15   # 1.1


ENCODER_MASK = 0x3F


@enum.unique
class NackReason(enum.IntEnum):
    UNKNOWN_COMMAND = 1
    BAD_LENGTH = 2
    BAD_ARGUMENT = 3
    RATE_TOO_HIGH = 4
    LINK_TOO_SLOW = 5
    BUSY = 6
    FAULT_DURING_AVERAGING = 7
    EEPROM_FAILED = 8
    ABORTED = 9            # 1.1
    FILTER_RANGE = 10      # 1.3


NACK_TEXT = {
    NackReason.UNKNOWN_COMMAND: "the device does not know this command (older firmware?)",
    NackReason.BAD_LENGTH: "wrong command length (expected {detail} bytes)",
    NackReason.BAD_ARGUMENT: "invalid argument ({detail})",
    NackReason.RATE_TOO_HIGH: "rate above the board's maximum of {detail} Hz",
    NackReason.LINK_TOO_SLOW: "the serial link carries at most {detail} Hz in this mode "
                              "(raise the baud rate or lower the rate)",
    NackReason.BUSY: "a tare or zero capture is still running (delta6 tare --abort stops it)",
    NackReason.FAULT_DURING_AVERAGING: "a sample was flagged while averaging "
                                       "(status {detail:#06x}); nothing was changed",
    NackReason.EEPROM_FAILED: "the EEPROM did not read back what was written (byte {detail})",
    NackReason.ABORTED: "aborted (an ABORT command stopped the averaging); nothing was changed",
    NackReason.FILTER_RANGE: "the low-pass cutoff must lie within 0.001 .. 0.45 x the sample "
                             "rate of {detail} Hz (0 turns the filter off)",
}


@enum.unique
class EventCode(enum.IntEnum):
    BOOT = 1
    CONFIG_DEFAULTS = 2


@enum.unique
class ConfigProblem(enum.IntEnum):
    """Why a stored configuration was rejected at boot (the CONFIG_DEFAULTS event's argument),
    or (RATE_LOWERED, INFO only, CONFIG_DEFAULTS clear) how it was adjusted to load."""

    ERASED = 1
    BAD_CRC = 2
    BAD_VERSION = 3
    OUT_OF_RANGE = 4
    RATE_LOWERED = 5       # 1.3


CONFIG_PROBLEM_TEXT = {
    ConfigProblem.ERASED: "EEPROM erased or never saved",
    ConfigProblem.BAD_CRC: "CRC mismatch",
    ConfigProblem.BAD_VERSION: "unknown layout version",
    ConfigProblem.OUT_OF_RANGE: "value out of range",
    ConfigProblem.RATE_LOWERED: "saved at a rate above this firmware's highest: loaded at its "
                                "highest (a low-pass cutoff that no longer fits is off), "
                                "everything else kept; SAVE_CONFIG stores it",
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
        Field("mode", "B"), Field("design_hash", "I"), Field("design_name", "s", MAX_NAME_CHARS + 1),
        Field("full_scale", "f", 6), Field("lsb_mantissa", "B", 6),
        Field("lsb_exponent", "b", 6), Field("rate_hz", "H"), Field("max_rate_hz", "H"),
        Field("status", "H"), Field("streaming", "B"), Field("config_problem", "B"),
        Field("baud", "I"), Field("serial_number", "I"), Field("zero_counts", "H", 6),
        Field("tare", "f", 6), Field("joint_limit_rad", "f"),
        # 1.1: the calibration the firmware applies (hash 0 and no name: none), and the boot
        # session.
        Field("calibration_hash", "I"), Field("calibration_name", "s", MAX_NAME_CHARS + 1),
        Field("boot_id", "H"),
        # 1.2: the on-chip residual model the firmware runs (hash 0 and no name: none).
        Field("model_hash", "I"), Field("model_name", "s", MAX_NAME_CHARS + 1),
        # 1.3: the wrench pipeline's configuration (SET_FILTER, SET_TOOL, SET_LIMITS).
        Field("filter_hz", "f"), Field("tool_translation", "f", 3),
        Field("tool_rpy", "f", 3), Field("limits", "H", 6),
        Field("max_rate_pipeline_hz", "H")]),
    RecordType.ACK: Layout("ACK", [_TYPE, _REQUEST, Field("command", "B"), Field("value", "I")]),
    RecordType.NACK: Layout("NACK", [_TYPE, _REQUEST, Field("command", "B"),
                                     Field("reason", "B"), Field("detail", "I")]),
    RecordType.TELEMETRY: Layout("TELEMETRY", [
        _TYPE, _REQUEST, Field("time_us", "I"), Field("status", "H"), Field("samples", "I"),
        Field("overruns", "H"), Field("encoder_errors", "H", 6), Field("solver_errors", "H"),
        Field("rx_frames", "H"), Field("rx_crc_errors", "H"), Field("rx_bad_frames", "H"),
        Field("rx_overflows", "H"), Field("tx_dropped", "H"), Field("responses_dropped", "H"),
        Field("loop_time_max_us", "H"), Field("loop_time_mean_us", "H"),
        Field("temperature_centi", "h"), Field("next_seq", "H"), Field("boot_id", "H")]),
    RecordType.EVENT: Layout("EVENT", [_TYPE, Field("code", "B"), Field("arg", "I")]),
}
RECORD_SIZES = {t: layout.size for t, layout in RECORD_LAYOUTS.items()}
#: Fields a minor version appended: a host reads the shorter records of an older device, each
#: missing field as the value here (1.1: the calibration and the boot id; 1.2: the model;
#: 1.3: the wrench pipeline).
APPENDED_FIELDS = {
    RecordType.INFO: {"calibration_hash": 0, "calibration_name": "", "boot_id": None,
                      "model_hash": 0, "model_name": "",
                      # no filter, the identity tool frame, no overload limits
                      "filter_hz": 0.0, "tool_translation": (0.0,) * 3,
                      "tool_rpy": (0.0,) * 3, "limits": (0,) * 6,
                      "max_rate_pipeline_hz": 0},
    RecordType.TELEMETRY: {"boot_id": None},
}
#: The first field each minor version appended to a record (its fields run to the next's).
APPENDED_SINCE = {
    RecordType.INFO: {1: "calibration_hash", 2: "model_hash", 3: "filter_hz"},
    RecordType.TELEMETRY: {1: "boot_id"},
}


def record_size(kind: RecordType, minor: int) -> int:
    """The payload size of a record of ``kind`` as minor version ``minor`` sent it."""
    layout = RECORD_LAYOUTS[kind]
    return min((layout.offsets[name] for since, name in APPENDED_SINCE.get(kind, {}).items()
                if since > minor), default=layout.size)


#: Every payload size a record of each type may have (one per minor version, oldest first).
RECORD_SIZES_BY_MINOR = {t: sorted({record_size(t, m) for m in range(VERSION[1] + 1)})
                         for t in RECORD_LAYOUTS}
#: The shortest payload of each type a host accepts: the record as version 1.0 defined it.
MIN_RECORD_SIZES = {t: min((layout.offsets[n] for n in APPENDED_FIELDS.get(t, ())),
                           default=layout.size) for t, layout in RECORD_LAYOUTS.items()}
INFO_SIZE_1_0 = MIN_RECORD_SIZES[RecordType.INFO]
#: INFO as version 1.1 sent it (without the model).
INFO_SIZE_1_1 = record_size(RecordType.INFO, 1)
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
    Command.ABORT: [],
    Command.SET_FILTER: [Field("cutoff_hz", "f")],
    Command.SET_TOOL: [Field("translation", "f", 3), Field("rpy", "f", 3)],
    Command.SET_LIMITS: [Field("limits", "H", 6)],
}.items()}
#: Argument format of each command (``struct``, after type and request id).
COMMAND_ARGS = {c: "".join(f.fmt for f in layout.fields[2:])
                for c, layout in COMMAND_LAYOUTS.items()}
COMMAND_SIZES = {c: layout.size for c, layout in COMMAND_LAYOUTS.items()}
MAX_RECORD_SIZE = max(RECORD_SIZES.values())

#: The configuration blob in the device's EEPROM (docs/protocol.md section 9), followed by
#: its CRC (most significant byte first, like frames).
_CONFIG_1 = [
    Field("magic", "H"), Field("layout", "B"), Field("size", "B"), Field("design_hash", "I"),
    Field("rate_hz", "H"), Field("mode", "B"), Field("tare_active", "B"), Field("tare", "f", 6),
    Field("zero_counts", "H", 6)]
#: Every layout a device loads, by layout version: each is the previous one with fields
#: appended (checked below), so the fields they share sit at one offset and the device
#: decodes an older blob with the newest offsets, its missing fields at their defaults.
CONFIG_LAYOUTS = {
    1: Layout("CONFIG", _CONFIG_1),
    2: Layout("CONFIG", _CONFIG_1 + [Field("filter_hz", "f"), Field("tool_translation", "f", 3),
                                     Field("tool_rpy", "f", 3), Field("limits", "H", 6)]),
}
CONFIG_LAYOUT_VERSION = max(CONFIG_LAYOUTS)
CONFIG_LAYOUT = CONFIG_LAYOUTS[CONFIG_LAYOUT_VERSION]
CONFIG_MAGIC = 0x3644           # "D6" little-endian
CONFIG_BLOB_SIZE = CONFIG_LAYOUT.size + CRC_SIZE
CONFIG_BLOB_SIZES = {v: layout.size + CRC_SIZE for v, layout in CONFIG_LAYOUTS.items()}
if any(not CONFIG_LAYOUTS[v + 1].starts_with(CONFIG_LAYOUTS[v]) for v in range(1, CONFIG_LAYOUT_VERSION)):
    raise AssertionError("each EEPROM layout is the previous one with fields appended")
#: Encoded length (no delimiter) of each record type: payload + CRC + one COBS code byte.
ENCODED_SIZES = {t: s + 3 for t, s in RECORD_SIZES.items()}
#: Every encoded length a record of each type may have (this version's, or an older minor's).
ENCODED_LENGTHS = {t: frozenset(s + 3 for s in sizes) for t, sizes in RECORD_SIZES_BY_MINOR.items()}


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
    config_problem: int    # a ConfigProblem: a rejection while CONFIG_DEFAULTS is set,
                           # or (1.3) RATE_LOWERED without it (0: none)
    baud: int
    serial_number: int
    zero_counts: tuple
    tare: tuple
    joint_limit_rad: float
    calibration_hash: int = 0      # 1.1; 0: the analytical model, no calibration
    calibration_name: str = ""
    boot_id: int | None = None      # 1.1: identifies the device's boot session
    model_hash: int = 0            # 1.2; 0: no on-chip residual model
    model_name: str = ""
    # 1.3: the wrench pipeline (defaults: what an older device does)
    filter_hz: float = 0.0          # low-pass cutoff, Hz; 0: off
    tool_translation: tuple = (0.0, 0.0, 0.0)   # tool point in {E}, m
    tool_rpy: tuple = (0.0, 0.0, 0.0)           # tool axes: roll, pitch, yaw about {E}, rad
    limits: tuple = (0,) * 6        # overload thresholds, counts of each axis's LSB; 0: none
    max_rate_pipeline_hz: int = 0   # the board's highest rate with the filter or tool frame
                                    # on (0: from a 1.0 device, which has neither)

    @property
    def limit_values(self) -> np.ndarray:
        """The overload thresholds in N and N*m (NaN where an axis has none)."""
        counts = np.asarray(self.limits, dtype=float)
        return np.where(counts > 0, counts * self.lsb, np.nan)

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
    boot_id: int | None = None      # 1.1

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

    Longer payloads than this version defines are accepted and their known prefix parsed
    (newer minor versions only append fields); a shorter one only at the exact size of an
    older minor version's record, read without the fields appended since (None); other
    lengths and unknown types raise ProtocolError (docs/protocol.md, section 11)."""
    if not payload:
        raise ProtocolError("empty frame")
    kind = payload[0]
    size = MIN_RECORD_SIZES.get(kind)
    if size is None:
        raise ProtocolError(f"unknown record type 0x{kind:02x}")
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
    layout = RECORD_LAYOUTS[kind]
    if len(payload) < layout.size:       # an older minor version's record
        sizes = RECORD_SIZES_BY_MINOR[kind]
        if len(payload) not in sizes:    # no version ends there: a record cut short
            raise ProtocolError(f"record type 0x{kind:02x} has {len(payload)} bytes: no "
                                f"version sends that ({', '.join(map(str, sizes))}, or more)")
        older = _older_layout(kind, len(payload))
        fields = dict(APPENDED_FIELDS[kind])
        fields.update(older.unpack(payload))
    else:
        fields = layout.unpack(payload)
    del fields["type"]
    if kind == RecordType.INFO:
        for key in ("design_name", "calibration_name", "model_name"):
            if isinstance(fields[key], bytes):
                fields[key] = fields[key].split(b"\x00", 1)[0].decode("ascii", "replace")
        fields["streaming"] = bool(fields["streaming"])
    return _RECORD_TUPLES[kind](**fields)


@functools.cache
def _older_layout(kind: RecordType, size: int) -> Layout:
    """The fields of ``kind`` that fit ``size`` bytes: the record of an older minor version."""
    layout = RECORD_LAYOUTS[kind]
    fields = [f for f in layout.fields
              if layout.offsets[f.name] + struct.calcsize("<" + f.fmt) <= size]
    return Layout(f"{layout.name}<{size}>", fields)


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


def encode_record(record, minor: int | None = None) -> bytes:
    """The frame of an INFO, ACK, NACK, TELEMETRY or EVENT record (the tuples above), as this
    version sends it, or as minor version ``minor`` did (0: 1.0, without the appended fields;
    1: 1.1, without the model; 2: 1.2, without the pipeline).
    An appended field the record does not have (None) is left off, with those after it and
    the rest of its minor version: the record is one a device of an older version sends."""
    kind = next(t for t, cls in _RECORD_TUPLES.items() if isinstance(record, cls))
    fields = record._asdict()
    layout = RECORD_LAYOUTS[kind]
    size = record_size(kind, VERSION[1] if minor is None else minor)
    for name in APPENDED_FIELDS.get(kind, ()):
        if fields[name] is None:     # sent as the last minor version without that field
            size = min(size, max(s for s in RECORD_SIZES_BY_MINOR[kind]
                                 if s <= layout.offsets[name]))
    if size < layout.size:
        layout = _older_layout(kind, size)
        fields = {k: v for k, v in fields.items() if k in layout.offsets}
    if kind == RecordType.INFO:
        name_field = RECORD_LAYOUTS[kind].field("design_name")
        fields.update(design_name=record.design_name.encode("ascii")[:name_field.count - 1],
                      streaming=int(record.streaming))
        for key in ("calibration_name", "model_name"):
            if key in fields:
                fields[key] = getattr(record, key).encode("ascii")[:name_field.count - 1]
    return frame(layout.pack(type=kind, **fields))


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


def impossible_counts(counts) -> np.ndarray:
    """Where raw counts lie beyond a 14-bit encoder's 0..16383 (a u16 on the wire can hold
    them; no encoder reads them): never an angle."""
    return np.asarray(counts) >= COUNTS_PER_TURN


def theta_values(counts, status, zero) -> np.ndarray:
    """(N, 6) encoder angles (rad) from raw counts; NaN where a sample sent no counts
    (:data:`NO_COUNTS`), its status flags that encoder as failed, or the count is impossible
    (:func:`impossible_counts`): all three are a read that gave no angle."""
    counts = np.asarray(counts)
    failed = ((np.asarray(status)[:, None] >> np.arange(6)) & 1) != 0
    missing = failed | (counts < 0) | impossible_counts(counts)
    return np.where(missing, np.nan, counts_to_theta(counts, zero))
