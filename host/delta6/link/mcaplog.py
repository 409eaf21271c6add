"""The Delta6 log as an MCAP file with ROS 2 messages (``docs/log-format.md``, "MCAP").

The same rows as the CSV log, as messages that ``ros2 bag play`` and Foxglove open as they are
(topics and types in :mod:`delta6.link.ros2msg`): per row a ``WrenchStamped`` and, when the row
has angles, a ``JointState``, both stamped with the row's time ``t`` (the device's clock); a
``Float64MultiArray`` with ``t`` itself and the optional columns (seq, status, host_t, temp_c),
so that a conversion back to CSV loses nothing; and a ``DiagnosticArray`` once per second of
log time with the status bits seen in that second. The header lines of the CSV log are the
file's ``delta6-log`` metadata record.

Message log times are the host's receive time as UNIX time (``host_t`` + the header's
``host_clock_offset``) when the log has both, else the row's time ``t``.

:class:`McapLogWriter` is a drop-in for :class:`delta6.link.logfile.LogWriter` (same methods,
the same ``.partial`` discipline); :func:`read_mcap` returns the same :class:`LogData`.
"""
from __future__ import annotations

import contextlib
import io
import os
import struct
from pathlib import Path

import numpy as np
from mcap.exceptions import EndOfFile, RecordLengthLimitExceeded
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
from mcap_ros2.decoder import DecoderFactory

from delta6.link import ros2msg as R
from delta6.link.logdata import (
    CORE_COLUMNS,
    FLUSH_EVERY,
    OPTIONAL_COLUMNS,
    PARTIAL_SUFFIX,
    SCHEMA_VERSION,
    LogData,
    LogError,
    PartialOnError,
    check_rows,
    int_column,
    meta_text,
    six_columns,
)

MAGIC = b"\x89MCAP0\r\n"
METADATA_NAME = "delta6-log"
#: Seconds of log time each DiagnosticArray summarises.
DIAGNOSTICS_PERIOD = 1.0


def is_mcap(path: str | Path) -> bool:
    """Whether the file starts with the MCAP magic (the reader's test; writers go by suffix)."""
    try:
        with open(path, "rb") as f:
            return f.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def log_times(t: np.ndarray, host_t, clock_offset: float | None) -> np.ndarray:
    """Message log times (ns): the host's receive time as UNIX time, ``host_t`` +
    ``clock_offset``, where both are known; the sample time ``t`` otherwise."""
    ns = np.round(np.asarray(t, dtype=float) * 1e9)
    if host_t is not None and clock_offset is not None:
        host = np.asarray(host_t, dtype=float)
        ns = np.where(np.isfinite(host), np.round((host + clock_offset) * 1e9), ns)
    return np.maximum(ns, 0).astype(np.int64)


class McapLogWriter(PartialOnError):
    """Write log rows to ``path`` (an MCAP file) through ``path.partial``; rename on close.

    The interface of :class:`~delta6.link.logfile.LogWriter`. ``meta`` may name the wrench's
    ``frame_id`` (default :data:`~delta6.link.ros2msg.DEFAULT_FRAME_ID`) and the
    ``host_clock_offset`` (s; UNIX time = host_t + offset) that dates the messages.
    Every block is closed into a chunk and handed to the operating system (a crash of the
    program loses none of it; ``mcap recover`` reads a ``.partial`` file); fsync every
    ``flush_every`` rows and at the end.
    """

    def __init__(self, path: str | Path, meta: dict | None = None,
                 optional: tuple[str, ...] = (), flush_every: int = FLUSH_EVERY,
                 keep_partial_on_error: bool = True):
        from delta6 import __version__
        unknown = set(optional) - set(OPTIONAL_COLUMNS)
        if unknown:
            raise ValueError(f"unknown optional columns {sorted(unknown)}")
        meta = {str(k): str(v) for k, v in dict(meta or {}).items()}
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + PARTIAL_SUFFIX)
        self.columns = CORE_COLUMNS + tuple(c for c in OPTIONAL_COLUMNS if c in optional)
        self.extra = ("t",) + self.columns[len(CORE_COLUMNS):]
        self.flush_every = max(1, flush_every)
        self.keep_partial_on_error = keep_partial_on_error
        self.rows = 0
        self._pending = 0
        self._last_stamp = -1
        #: The file's size after the last block that reached the OS whole, and whether a write
        #: failed since (a full disk): the file is then cut back to that size when closed.
        self._good_size = 0
        self._broken = False
        frame_id = meta.get("frame_id", R.DEFAULT_FRAME_ID)
        offset = meta.get("host_clock_offset")
        self.clock_offset = float(offset) if offset not in (None, "") else None
        self._messages = R.SampleMessages(frame_id, self.extra)
        self._diagnostics = (R.DiagnosticsWindow(frame_id, _hardware_id(meta), DIAGNOSTICS_PERIOD)
                             if "status" in self.extra else None)
        try:
            self._file = open(self.partial, "wb")
        except OSError as exc:
            raise LogError(f"cannot create {self.partial}: {exc.strerror}") from None
        self._mcap = Writer(self._file, compression=CompressionType.ZSTD)
        try:
            with self._writing():
                self._mcap.start(profile="ros2", library=f"delta6 {__version__}")
                self._channels = {}
                for topic, datatype in R.TOPICS.items():
                    schema = self._mcap.register_schema(datatype, "ros2msg",
                                                        R.definition(datatype).encode())
                    self._channels[topic] = self._mcap.register_channel(topic, "cdr", schema)
                self._mcap.add_metadata(METADATA_NAME, {
                    **{meta_text(key): meta_text(value) for key, value in meta.items()},
                    "schema": str(SCHEMA_VERSION), "columns": ",".join(self.columns)})
                self._to_os()
        except LogError:
            # Not even the header fits: no file is left behind to be refused next time.
            self._close_quietly()
            self.partial.unlink(missing_ok=True)
            raise

    # -- writing ---------------------------------------------------------------------------

    def write(self, t: float, theta, wrench, **optional) -> None:
        """One sample. ``theta`` or ``wrench`` may be None (no value)."""
        block = {k: None if v is None else np.asarray([v], float) for k, v in optional.items()}
        self.write_block(np.asarray([t], float),
                         None if theta is None else np.asarray([theta], float),
                         None if wrench is None else np.asarray([wrench], float), **block)

    def write_block(self, t: np.ndarray, theta: np.ndarray | None, wrench: np.ndarray | None,
                    **optional: np.ndarray) -> None:
        t = np.asarray(t, dtype=float)
        n = len(t)
        if n == 0:
            return
        sec, nanosec = R.stamp(t)
        stamps = sec * 1_000_000_000 + nanosec
        steps = np.diff(np.concatenate(([self._last_stamp], stamps)))
        if (steps <= 0).any():
            raise LogError(f"{self.path}: time must increase by at least 1 ns from sample to "
                           f"sample (ROS stamps count nanoseconds); sample "
                           f"{self.rows + int(np.argmax(steps <= 0)) + 1} does not")
        self._last_stamp = int(stamps[-1])
        extra = np.stack([t] + [_column(optional.get(c), n) for c in self.extra[1:]], axis=1)
        log_time = log_times(t, optional.get("host_t"), self.clock_offset)
        seq = optional.get("seq")
        sequence = (np.arange(self.rows, self.rows + n) if seq is None
                    else np.nan_to_num(np.asarray(seq, float), nan=0)).astype(np.int64) & 0xFFFFFFFF
        add = self._mcap.add_message
        for row, topic, data in self._messages.encode(t, six_columns(theta, n), six_columns(wrench, n),
                                                      extra):
            lt = int(log_time[row])
            add(self._channels[topic], lt, data, lt, int(sequence[row]))
        if self._diagnostics is not None:
            for lt, data in self._diagnostics.add(t, extra[:, self.extra.index("status")],
                                                  log_time):
                add(self._channels[R.TOPIC_STATUS], lt, data, lt, 0)
        with self._writing():
            self._to_os()    # the chunk to the OS: a crash of this process loses none of it
        self.rows += n       # only rows that reached the OS are counted
        self._pending += n
        if self._pending >= self.flush_every:
            self.flush()

    def flush(self) -> None:
        """Everything written so far to the OS and on to the disk (fsync)."""
        with self._writing():
            self._to_os()
            os.fsync(self._file.fileno())
        self._pending = 0

    def _to_os(self) -> None:
        self._mcap.flush()
        self._file.flush()
        self._good_size = self._file.tell()

    @contextlib.contextmanager
    def _writing(self):
        """A failed write (a full disk) as one line; the file is cut back to its last whole
        block when closed (each chunk also has its own CRC, so a cut one is never read as
        data)."""
        if self._broken:
            raise LogError(f"cannot write {self.partial}: an earlier write failed")
        try:
            yield
        except OSError as exc:
            self._broken = True
            raise LogError(f"cannot write {self.partial}: {exc.strerror or exc}; it keeps the "
                           f"{self.rows} rows written before") from None

    def _close_quietly(self) -> None:
        try:
            self._file.close()
        except OSError:     # the buffered part of the failed block: dropped by the cut below
            pass

    def close(self, complete: bool = True) -> Path:
        """Finish the file (summary and footer). A complete log is renamed to its final name;
        an incomplete one keeps the ``.partial`` suffix. Returns the path on disk."""
        if self._file.closed:
            return self.path if complete else self.partial
        if not self._broken:
            try:
                with self._writing():
                    if self._diagnostics is not None:
                        for lt, data in self._diagnostics.finish():
                            self._mcap.add_message(self._channels[R.TOPIC_STATUS], lt, data,
                                                   lt, 0)
                    self._mcap.finish()
                    self._file.flush()
                    os.fsync(self._file.fileno())
            except LogError:
                pass                # the file is broken now: handled below
        self._close_quietly()
        if self._broken:
            # A write failed: no summary (no room for it), and the file cut back to the last
            # block that reached the OS whole, so that it ends on a whole chunk.
            os.truncate(self.partial, self._good_size)
            if complete:
                raise LogError(f"cannot complete {self.path}: a write failed; its {self.rows} "
                               f"rows are in {self.partial}")
            return self.partial
        if complete:
            os.replace(self.partial, self.path)
            return self.path
        return self.partial



def _hardware_id(meta: dict) -> str:
    return " ".join(meta[k] for k in ("design", "serial_number") if k in meta)



def _column(values, n: int) -> np.ndarray:
    return np.full(n, np.nan) if values is None else np.asarray(values, dtype=float).reshape(n)


# --- reading ------------------------------------------------------------------------------

def read_mcap(path: str | Path, *, require_complete_rows: bool = True) -> LogData:
    """Read an MCAP log (ours, or any file with WrenchStamped on /delta6/wrench) into the same
    :class:`LogData` as the CSV reader, with the same checks and one-line errors."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot be read ({exc.strerror})") from None
    meta, topics, cut = _records(path, data, cut_ok=path.name.endswith(PARTIAL_SUFFIX))
    if meta.get("schema", str(SCHEMA_VERSION)) != str(SCHEMA_VERSION):
        raise LogError(f"{path}: log schema {meta['schema']} is not supported "
                       f"(this version reads schema {SCHEMA_VERSION})")
    if R.TOPIC_WRENCH not in topics or not topics[R.TOPIC_WRENCH][1]:
        raise LogError(f"{path}: no samples (no {R.TOPIC_WRENCH} messages)")
    frame_id = meta.get("frame_id", R.DEFAULT_FRAME_ID)

    wrench_rows = _decode(path, topics[R.TOPIC_WRENCH], R.wrench_stamped(frame_id),
                          lambda m: (m.header.stamp.sec, m.header.stamp.nanosec,
                                     [m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                                      m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z]))
    keys = _ns(wrench_rows)
    order = np.argsort(keys, kind="stable")
    keys = keys[order]
    wrench = np.asarray(wrench_rows["wrench"], float)[order]
    n = len(keys)
    if np.any(np.diff(keys) == 0):
        raise LogError(f"{path}: two wrench messages carry the same stamp")
    t = keys / 1e9

    theta = np.full((n, 6), np.nan)
    present = []           # per other topic: which rows have its message
    if topics.get(R.TOPIC_JOINTS, (None, []))[1]:
        rows = _decode(path, topics[R.TOPIC_JOINTS], R.joint_state(frame_id),
                       lambda m: (m.header.stamp.sec, m.header.stamp.nanosec,
                                  _named_positions(path, m)))
        at = _match(path, keys, _ns(rows), R.TOPIC_JOINTS)
        theta[at] = rows["position"]
        present.append(np.isin(np.arange(n), at))

    columns = meta.get("columns", ",".join(CORE_COLUMNS)).split(",")
    optional_names = [c for c in OPTIONAL_COLUMNS if c in columns]
    extra = {}
    if topics.get(R.TOPIC_SAMPLE, (None, []))[1]:
        labels = ("t",) + tuple(optional_names)
        rows = _decode(path, topics[R.TOPIC_SAMPLE], R.float64_array(",".join(labels), len(labels)),
                       lambda m: _labelled(path, m, labels))
        values = np.asarray(rows["data"], float).reshape(-1, len(labels))
        at = _match(path, keys, np.round(values[:, 0] * 1e9).astype(np.int64), R.TOPIC_SAMPLE)
        table = np.full((n, len(labels)), np.nan)
        table[at] = values
        present.append(np.isin(np.arange(n), at))
        t = np.where(np.isnan(table[:, 0]), t, table[:, 0])
        extra = {name: table[:, i + 1] for i, name in enumerate(optional_names)}
    elif optional_names:
        raise LogError(f"{path}: no {R.TOPIC_SAMPLE} messages for the columns "
                       f"{', '.join(optional_names)}")

    if cut and n:
        # A killed writer's last samples may have lost their other topics' messages to the
        # cut: the rows after the last one with every topic's message go (NaN values are
        # data, not a cut). The metadata says so only when one went: a cut that fell
        # between whole samples dropped nothing.
        whole = np.logical_and.reduce(present) if present else np.ones(n, bool)
        keep = n - int(np.argmax(whole[::-1])) if whole.any() else 0
        if keep == 0:
            raise LogError(f"{path}: no whole sample before the cut")
        if keep < n:
            meta["cut_row_dropped"] = "1"
        t, theta, wrench = t[:keep], theta[:keep], wrench[:keep]
        extra = {name: values[:keep] for name, values in extra.items()}
    check_rows(path, t, theta, wrench, lambda i: f"sample {i + 1}", require_complete_rows)
    meta.pop("columns", None)
    return LogData(t=t, theta=theta, wrench=wrench, seq=int_column(extra.get("seq")),
                   status=int_column(extra.get("status")), host_t=extra.get("host_t"),
                   temp_c=extra.get("temp_c"), meta=meta)


def _records(path: Path, data: bytes, cut_ok: bool = False):
    """The metadata, per topic (schema, [messages]), and whether the file ends inside a
    record. ``cut_ok``: the file is what a killed writer left (``.partial``): it may end
    inside a record, and the records before the cut are kept (a chunk is read whole or not
    at all, and each carries a CRC)."""
    schemas, channels, messages, meta = {}, {}, {}, {}
    cut = False
    try:
        for record in StreamReader(io.BytesIO(data), validate_crcs=True,
                                   record_size_limit=len(data)).records:
            if isinstance(record, Message):
                messages.setdefault(record.channel_id, []).append(record.data)
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Metadata) and record.name == METADATA_NAME:
                meta = dict(record.metadata)
    # A record, its header, or a length longer than what is left of the file: cut short.
    except (EndOfFile, struct.error, RecordLengthLimitExceeded) as exc:
        if not (cut_ok and (channels or messages)):
            detail = str(exc)[:60]
            raise LogError(f"{path}: not a readable MCAP file (it ends inside a record"
                           f"{'' if cut_ok else '; a log cut by a crash keeps its .partial name'}"
                           f"{': ' + detail if detail else ''})") from None
        cut = True
    except Exception as exc:   # the mcap reader's many ways to say "damaged": one line
        raise LogError(f"{path}: not a readable MCAP file ({type(exc).__name__}: "
                       f"{str(exc)[:80]})") from None
    topics = {}
    for cid, channel in channels.items():
        schema = schemas.get(channel.schema_id)
        if channel.topic in topics or schema is None:
            continue
        if channel.message_encoding != "cdr" or schema.encoding != "ros2msg":
            raise LogError(f"{path}: {channel.topic} is not ROS 2 CDR "
                           f"({channel.message_encoding}, {schema.encoding})")
        topics[channel.topic] = (schema, messages.get(cid, []))
    return meta, topics, cut


def _decode(path: Path, topic, layout: R.FixedLayout, fields) -> np.ndarray:
    """A topic's messages as the layout's structured array: all at once when they have our
    layout, else one by one with the generic ROS 2 decoder (``fields`` picks the values)."""
    schema, messages = topic
    rows = layout.decode(messages)
    if rows is not None:
        return rows
    try:
        decode = DecoderFactory().decoder_for("cdr", schema)
        values = [fields(decode(m)) for m in messages]
        out = np.zeros(len(messages), dtype=layout.dtype)
        for name, column in zip(layout.dtype.names, zip(*values)):
            out[name] = column
    except LogError:
        raise
    except Exception as exc:
        raise LogError(f"{path}: cannot decode {schema.name} messages ({type(exc).__name__}: "
                       f"{str(exc)[:80]})") from None
    return out


def _named_positions(path: Path, message) -> list[float]:
    names = list(message.name)
    try:
        return [float(message.position[names.index(j)]) for j in R.JOINT_NAMES]
    except (ValueError, IndexError):
        raise LogError(f"{path}: a JointState lacks the joints {', '.join(R.JOINT_NAMES)}") from None


def _labelled(path: Path, message, labels) -> tuple:
    dims = message.layout.dim
    found = tuple(dims[0].label.split(",")) if dims else ()
    if found != labels or len(message.data) != len(labels):
        raise LogError(f"{path}: {R.TOPIC_SAMPLE} carries {','.join(found) or 'no labels'}, "
                       f"the metadata says {','.join(labels)}")
    return (list(message.data),)


def _ns(rows: np.ndarray) -> np.ndarray:
    return rows["sec"].astype(np.int64) * 1_000_000_000 + rows["nanosec"].astype(np.int64)


def _match(path: Path, keys: np.ndarray, stamps: np.ndarray, topic: str) -> np.ndarray:
    """Row index of each message stamp; every stamp must be a wrench message's."""
    at = np.searchsorted(keys, stamps)
    at = np.minimum(at, len(keys) - 1)
    bad = keys[at] != stamps
    if bad.any():
        raise LogError(f"{path}: a {topic} message at {stamps[bad][0] / 1e9:.9f} s has no "
                       f"{R.TOPIC_WRENCH} message")
    if len(np.unique(at)) != len(at):
        raise LogError(f"{path}: two {topic} messages for one sample")
    return at
