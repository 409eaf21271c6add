"""The ROS 2 messages Delta6 publishes (MCAP logs, the Foxglove live view), CDR-encoded.

Topics and types (``docs/log-format.md``, "MCAP"):

=====================  ===================================  ==================================
``/delta6/wrench``     ``geometry_msgs/msg/WrenchStamped``  the wrench, one per sample
``/delta6/joints``     ``sensor_msgs/msg/JointState``       encoder angles theta_e1..6 (rad)
``/delta6/sample``     ``std_msgs/msg/Float64MultiArray``   the log row's other columns
``/delta6/status``     ``diagnostic_msgs/msg/DiagnosticArray``  the status word, at a low rate
=====================  ===================================  ==================================

A message whose strings are fixed (the frame id, the joint names, the column labels) has a
fixed layout: one byte template and a numpy structured dtype for its numbers encode a whole
block of samples at once. The layouts follow the OMG CDR rules ROS 2 uses (little-endian
encapsulation 0x0001; primitives aligned to their size counted from after the 4-byte
encapsulation header); the tests decode them with the independent ``mcap_ros2`` decoder.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from delta6.link.protocol import ENCODER_MASK, Status

TOPIC_WRENCH = "/delta6/wrench"
TOPIC_JOINTS = "/delta6/joints"
TOPIC_SAMPLE = "/delta6/sample"
TOPIC_STATUS = "/delta6/status"
DEFAULT_FRAME_ID = "delta6_e"
JOINT_NAMES = tuple(f"theta_e{i}" for i in range(1, 7))

WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
JOINT_STATE = "sensor_msgs/msg/JointState"
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
#: Every topic and its message type.
TOPICS = {TOPIC_WRENCH: WRENCH_STAMPED, TOPIC_JOINTS: JOINT_STATE,
          TOPIC_SAMPLE: FLOAT64_MULTI_ARRAY, TOPIC_STATUS: DIAGNOSTIC_ARRAY}

# --- message definitions (the ``ros2msg`` schema text: the type, then each dependency) ------

_SEPARATOR = "=" * 80
_DEFINITIONS = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Wrench": "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque",
    "geometry_msgs/WrenchStamped": "std_msgs/Header header\ngeometry_msgs/Wrench wrench",
    "sensor_msgs/JointState": ("std_msgs/Header header\nstring[] name\nfloat64[] position\n"
                               "float64[] velocity\nfloat64[] effort"),
    "std_msgs/MultiArrayDimension": "string label\nuint32 size\nuint32 stride",
    "std_msgs/MultiArrayLayout": "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset",
    "std_msgs/Float64MultiArray": "std_msgs/MultiArrayLayout layout\nfloat64[] data",
    "diagnostic_msgs/KeyValue": "string key\nstring value",
    "diagnostic_msgs/DiagnosticStatus": (
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\n"
        "string message\nstring hardware_id\ndiagnostic_msgs/KeyValue[] values"),
    "diagnostic_msgs/DiagnosticArray": ("std_msgs/Header header\n"
                                        "diagnostic_msgs/DiagnosticStatus[] status"),
}
_DEPENDENCIES = {
    WRENCH_STAMPED: ("std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Wrench",
                     "geometry_msgs/Vector3"),
    JOINT_STATE: ("std_msgs/Header", "builtin_interfaces/Time"),
    FLOAT64_MULTI_ARRAY: ("std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension"),
    DIAGNOSTIC_ARRAY: ("std_msgs/Header", "builtin_interfaces/Time",
                       "diagnostic_msgs/DiagnosticStatus", "diagnostic_msgs/KeyValue"),
}


def definition(datatype: str) -> str:
    """The ``ros2msg`` schema text of ``datatype`` (``pkg/msg/Name``) with its dependencies."""
    package, _, name = datatype.split("/")
    parts = [_DEFINITIONS[f"{package}/{name}"]]
    for dep in _DEPENDENCIES[datatype]:
        parts += [_SEPARATOR, f"MSG: {dep}", _DEFINITIONS[dep]]
    return "\n".join(parts) + "\n"


# --- CDR ---------------------------------------------------------------------------------

ENCAPSULATION = b"\x00\x01\x00\x00"     # CDR, little-endian


class CdrBuilder:
    """Lays out one message: constants go into the template, named numbers become fields of
    the structured dtype (offsets include the encapsulation header)."""

    def __init__(self):
        self.buf = bytearray()
        self.fields: dict[str, tuple[str, int]] = {}

    def _align(self, n: int) -> None:
        self.buf += b"\x00" * (-len(self.buf) % n)

    def _put(self, fmt: str, value=0, name: str | None = None) -> None:
        size = struct.calcsize("<" + fmt)
        self._align(size)
        if name is not None:
            self.fields[name] = ("<" + fmt, len(ENCAPSULATION) + len(self.buf))
        self.buf += struct.pack("<" + fmt, value)

    def u8(self, value: int) -> None:
        self._put("B", value)

    def i32(self, value: int = 0, name: str | None = None) -> None:
        self._put("i", value, name)

    def u32(self, value: int = 0, name: str | None = None) -> None:
        self._put("I", value, name)

    def string(self, text: str) -> None:
        data = text.encode("utf-8")
        if b"\x00" in data:
            raise ValueError(f"a ROS string cannot hold NUL bytes: {text!r}")
        self.u32(len(data) + 1)
        self.buf += data + b"\x00"

    def strings(self, texts) -> None:
        texts = list(texts)
        self.u32(len(texts))
        for text in texts:
            self.string(text)

    def f64s(self, name: str, n: int, sequence: bool) -> None:
        """``n`` float64 in a row: a ``float64[]`` (length first) or fixed members."""
        if sequence:
            self.u32(n)
        if n:
            self._align(8)
            self.fields[name] = (f"({n},)<f8", len(ENCAPSULATION) + len(self.buf))
            self.buf += b"\x00" * (8 * n)

    def header(self, frame_id: str) -> None:
        self.i32(name="sec")
        self.u32(name="nanosec")
        self.string(frame_id)

    def layout(self) -> "FixedLayout":
        template = ENCAPSULATION + bytes(self.buf)
        names = list(self.fields)
        dtype = np.dtype({"names": names, "formats": [self.fields[n][0] for n in names],
                          "offsets": [self.fields[n][1] for n in names],
                          "itemsize": len(template)})
        return FixedLayout(template, dtype)


@dataclass(frozen=True)
class FixedLayout:
    """A message type with fixed strings: ``encode`` fills a block of messages at once."""

    template: bytes
    dtype: np.dtype
    _static: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        mask = np.ones(len(self.template), bool)
        for name in self.dtype.names:
            fmt, offset = self.dtype.fields[name][:2]
            mask[offset:offset + fmt.itemsize] = False
        object.__setattr__(self, "_static", mask)

    @property
    def size(self) -> int:
        return len(self.template)

    def encode(self, **columns) -> list[bytes]:
        """One message per row of the given columns (every field of the layout)."""
        n = len(next(iter(columns.values())))
        buf = bytearray(self.template * n)      # filled in place: padding and constants stay
        raw = np.frombuffer(buf, dtype=self.dtype)
        for name in self.dtype.names:
            raw[name] = columns[name]
        data = bytes(buf)
        size = self.size
        return [data[i:i + size] for i in range(0, n * size, size)]

    def decode(self, messages: list[bytes]) -> np.ndarray | None:
        """The numbers of messages of this exact layout (constants included), or None when any
        message differs from it (another writer's strings: decode those generically)."""
        if not messages or any(len(m) != self.size for m in messages):
            return None
        block = np.frombuffer(b"".join(messages), dtype=np.uint8).reshape(len(messages), -1)
        template = np.frombuffer(self.template, dtype=np.uint8)
        if not np.array_equal(block[:, self._static], np.broadcast_to(
                template[self._static], (len(messages), int(self._static.sum())))):
            return None
        return np.frombuffer(block.tobytes(), dtype=self.dtype)


def wrench_stamped(frame_id: str) -> FixedLayout:
    b = CdrBuilder()
    b.header(frame_id)
    b.f64s("wrench", 6, sequence=False)        # force x y z, torque x y z
    return b.layout()


def joint_state(frame_id: str, names=JOINT_NAMES) -> FixedLayout:
    b = CdrBuilder()
    b.header(frame_id)
    b.strings(names)
    b.f64s("position", len(names), sequence=True)
    b.f64s("velocity", 0, sequence=True)
    b.f64s("effort", 0, sequence=True)
    return b.layout()


def float64_array(label: str, n: int) -> FixedLayout:
    b = CdrBuilder()
    b.u32(1)                 # one dimension
    b.string(label)
    b.u32(n)                 # size
    b.u32(n)                 # stride
    b.u32(0)                 # data_offset
    b.f64s("data", n, sequence=True)
    return b.layout()


def stamp(t) -> tuple[np.ndarray, np.ndarray]:
    """Seconds -> (sec, nanosec) of builtin_interfaces/Time, rounded to the nanosecond."""
    ns = np.round(np.asarray(t, dtype=float) * 1e9).astype(np.int64)
    return ns // 1_000_000_000, ns % 1_000_000_000


# --- diagnostics (variable strings: one message at a time, at a low rate) ------------------

OK, WARN, ERROR, STALE = 0, 1, 2, 3


def diagnostic_array(t: float, frame_id: str, level: int, name: str, message: str,
                     hardware_id: str, values: dict[str, str]) -> bytes:
    b = CdrBuilder()
    sec, nanosec = stamp([t])
    b.i32(int(sec[0]))
    b.u32(int(nanosec[0]))
    b.string(frame_id)
    b.u32(1)                 # one DiagnosticStatus
    b.u8(level)
    b.string(name)
    b.string(message)
    b.string(hardware_id)
    b.u32(len(values))
    for key, value in values.items():
        b.string(key)
        b.string(value)
    return ENCAPSULATION + bytes(b.buf)


# --- what one block of log rows becomes ---------------------------------------------------

class SampleMessages:
    """The per-row messages of a block of samples: a WrenchStamped for every row, a JointState
    for every row with an angle, and a Float64MultiArray of ``t`` and the ``extra`` columns
    (their labels; the first is ``t``)."""

    def __init__(self, frame_id: str, extra: tuple[str, ...]):
        if not extra or extra[0] != "t":
            raise ValueError("the sample array starts with t")
        self.extra = tuple(extra)
        self._wrench = wrench_stamped(frame_id)
        self._joints = joint_state(frame_id)
        self._sample = float64_array(",".join(self.extra), len(self.extra))

    def encode(self, t: np.ndarray, theta: np.ndarray, wrench: np.ndarray,
               extra: np.ndarray) -> list[tuple[int, str, bytes]]:
        """(row, topic, CDR message) in row order; ``extra`` is (n, len(self.extra))."""
        sec, nanosec = stamp(t)
        has_theta = np.isfinite(theta).any(axis=1)
        wrenches = self._wrench.encode(sec=sec, nanosec=nanosec, wrench=wrench)
        samples = self._sample.encode(data=extra)
        joints = iter(self._joints.encode(sec=sec[has_theta], nanosec=nanosec[has_theta],
                                          position=theta[has_theta]))
        out = []
        for i in range(len(t)):
            out.append((i, TOPIC_WRENCH, wrenches[i]))
            if has_theta[i]:
                out.append((i, TOPIC_JOINTS, next(joints)))
            out.append((i, TOPIC_SAMPLE, samples[i]))
        return out


#: Status bits that make the diagnostic level ERROR (no wrench or no angle) or WARN.
ERROR_BITS = ENCODER_MASK | Status.SOLVER_ERROR | Status.WRENCH_INVALID
WARN_BITS = Status.OVERRANGE | Status.JOINT_LIMIT | Status.LOOP_OVERRUN | Status.TX_OVERFLOW


def status_level(status: int) -> int:
    """The diagnostic level of a status word (the OR of a window's samples)."""
    if status & ERROR_BITS:
        return ERROR
    return WARN if status & WARN_BITS else OK


def status_text(status: int) -> str:
    names = [f.name.lower() for f in Status if f & status]
    return ",".join(names) if names else "ok"


class DiagnosticsWindow:
    """One DiagnosticArray per ``period`` seconds of sample time, with the OR of the status words
    of its samples (a flag raised by one sample is not lost between reports), the number of
    samples, how many were flagged, and the last status word."""

    def __init__(self, frame_id: str, hardware_id: str = "", period: float = 1.0):
        self.frame_id, self.hardware_id, self.period = frame_id, hardware_id, period
        self._start: float | None = None
        self._bits = self._count = self._flagged = self._last = 0
        self._last_t = self._last_log_time = None

    def add(self, t: np.ndarray, status: np.ndarray, log_time: np.ndarray) -> list[tuple[int, bytes]]:
        """(log time, message) of every window the block completes."""
        words = np.nan_to_num(np.asarray(status, dtype=float), nan=0).astype(np.int64)
        out = []
        begin = 0
        if self._start is None:
            self._start = float(t[0])
        while begin < len(t):
            cut = np.flatnonzero(t[begin:] >= self._start + self.period)
            end = begin + int(cut[0]) if cut.size else len(t)
            part = words[begin:end]
            if part.size:
                self._bits |= int(np.bitwise_or.reduce(part))
                self._count += part.size
                self._flagged += int(np.count_nonzero(part & (ERROR_BITS | WARN_BITS)))
                self._last = int(part[-1])
            if not cut.size:
                break
            out.append((int(log_time[end]), self._message(float(t[end]))))
            self._start, begin = float(t[end]), end
        self._last_t, self._last_log_time = float(t[-1]), int(log_time[-1])
        return out

    def finish(self) -> list[tuple[int, bytes]]:
        """The report of the window in progress, if it has samples."""
        if not self._count:
            return []
        return [(self._last_log_time, self._message(self._last_t))]

    def _message(self, t: float) -> bytes:
        data = diagnostic_array(t, self.frame_id, status_level(self._bits), "delta6",
                                status_text(self._bits), self.hardware_id,
                                {"status": f"0x{self._bits:04x}", "samples": str(self._count),
                                 "flagged": str(self._flagged), "last_status": f"0x{self._last:04x}"})
        self._bits = self._count = self._flagged = 0
        return data
