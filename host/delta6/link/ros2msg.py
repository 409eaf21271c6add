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
