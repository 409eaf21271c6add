"""The Delta6 log format: CSV with a commented header (``docs/log-format.md``), and the front
door to every log format: :func:`open_log_writer` picks the format from the file name (``.mcap``:
MCAP with ROS 2 messages, :mod:`delta6.link.mcaplog`; anything else: CSV) and :func:`read_log`
reads either, by the file's first bytes, into the same :class:`LogData`.

One format for everything that records samples: the host logger (``delta6 log``), the
capture decoder (``delta6 decode``), the digital twin (``delta6 simulate``) and the gap
diagnosis (``delta6 diagnose``, which reads it). Writers stream into ``FILE.partial`` and
rename it to ``FILE`` only on a clean close, so a file without the suffix is always complete,
and a crash leaves everything flushed so far in the ``.partial`` file (flushed to the operating
system: every block, and every ``flush_every`` rows; to the disk, fsync: every ``flush_every``
rows and at the end).
"""
from __future__ import annotations

import io
import math
import os
from pathlib import Path

import numpy as np

from delta6.link import mcaplog
from delta6.link.logdata import (
    CORE_COLUMNS,
    FLUSH_EVERY,
    OPTIONAL_COLUMNS,
    PARTIAL_SUFFIX,
    SCHEMA_VERSION,
    THETA_COLUMNS,
    UNITS,
    WRENCH_COLUMNS,
    LogData,
    LogError,
    PartialOnError,
    check_rows,
    int_column,
    meta_text,
    six_columns,  # noqa: F401 - re-exported: the log API is this module's
)

MAGIC = "delta6-log"
_FLOAT_FORMAT = "%.9g"      # float32 values survive the round trip exactly
#: Times with fixed decimals: device times are whole microseconds, so they are written
#: exactly at any length of run (9 significant digits lose microseconds past 1000 s).
_TIME_FORMAT = "%.6f"
_TIME_COLUMNS = ("t", "host_t")
_COLUMN_FORMATS = {"t": _TIME_FORMAT, "host_t": _TIME_FORMAT, "seq": "%d", "status": "%d"}


def header_lines(meta: dict, columns: tuple[str, ...]) -> list[str]:
    lines = [f"# {MAGIC} schema={SCHEMA_VERSION}"]
    for key, value in meta.items():
        if "=" in key:
            raise ValueError(f"metadata key {key!r} must not hold '='")
        lines.append(f"# {meta_text(key)}={meta_text(value)}")
    lines.append("# units: " + "; ".join(f"{k} {v}" for k, v in UNITS.items()))
    lines.append(",".join(columns))
    return lines


class LogWriter(PartialOnError):
    """Write samples to ``path`` through ``path.partial``; rename on :meth:`close`.

    ``meta`` goes into the header as ``# key=value`` lines (conventionally ``design``,
    ``design_hash``, ``source``, ``wrench_source``). ``optional`` picks the optional columns
    to write. Rows reach the operating system as they are written (one write per block; single
    rows every ``flush_every``) and the disk (fsync) every ``flush_every`` rows, so a crash of
    the program loses no block and a power cut at most the rows since the last fsync.
    A write that fails (a full disk) is undone to the last complete row and raises
    :class:`LogError`: the file never ends in a cut row. ``overwrite=False`` refuses to replace
    an existing file or an existing ``.partial`` (what an interrupted run left).
    Use as a context manager: a clean exit renames the file; an exception leaves the
    ``.partial`` file (its rows are good, but the run did not end) unless
    ``keep_partial_on_error`` is False.
    """

    def __init__(self, path: str | Path, meta: dict | None = None,
                 optional: tuple[str, ...] = (), flush_every: int = FLUSH_EVERY,
                 keep_partial_on_error: bool = True, overwrite: bool = True):
        unknown = set(optional) - set(OPTIONAL_COLUMNS)
        if unknown:
            raise ValueError(f"unknown optional columns {sorted(unknown)}")
        self.path = Path(path)
        self.partial = partial_path(self.path)
        self.columns = CORE_COLUMNS + tuple(c for c in OPTIONAL_COLUMNS if c in optional)
        self.flush_every = max(1, flush_every)
        self.keep_partial_on_error = keep_partial_on_error
        self.rows = 0                # rows in the file (or, for write(), queued for it)
        self._pending = 0            # rows since the last fsync
        self._queued: list[str] = []  # rows from write() not yet handed to the OS
        self._size = 0               # bytes of complete rows in the file
        self._synced_rows = 0
        if not overwrite:
            for existing in (self.path, self.partial):
                if existing.exists():
                    raise LogError(f"{existing} exists (pass --force to replace it)")
        self._row_format = ",".join(_COLUMN_FORMATS.get(c, _FLOAT_FORMAT) for c in self.columns)
        try:
            self._fd = os.open(self.partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        except OSError as exc:
            raise LogError(f"cannot create {self.partial}: {exc.strerror}") from None
        self._closed = False
        self._append("\n".join(header_lines(dict(meta or {}), self.columns)) + "\n", 0)

    # -- writing ---------------------------------------------------------------------------

    def write(self, t: float, theta, wrench, **optional) -> None:
        """One sample. ``theta`` or ``wrench`` may be None (written as empty fields)."""
        values = [t, *(_six(theta)), *(_six(wrench))]
        values += [optional.get(c) for c in self.columns[len(CORE_COLUMNS):]]
        self._queued.append(",".join(_cell(v, c) for v, c in zip(values, self.columns)) + "\n")
        self.rows += 1
        if len(self._queued) >= self.flush_every:
            self.flush()

    def write_block(self, t: np.ndarray, theta: np.ndarray, wrench: np.ndarray,
                    **optional: np.ndarray) -> None:
        """Many samples at once (vectorised formatting, for the simulator and the decoder)."""
        n = len(t)
        if n == 0:
            return
        cols = [np.asarray(t, float)[:, None], six_columns(theta, n), six_columns(wrench, n)]
        for name in self.columns[len(CORE_COLUMNS):]:
            value = optional.get(name)
            cols.append(np.full((n, 1), np.nan) if value is None
                        else np.asarray(value, float).reshape(n, 1))
        table = np.hstack(cols)
        fmt = self._row_format
        if np.isnan(table).any():      # an integer column cannot print NaN: as floats
            fmt = ",".join(_FLOAT_FORMAT if f == "%d" else f for f in fmt.split(","))
        buf = io.StringIO()
        np.savetxt(buf, table, fmt=fmt.split(","), delimiter=",")
        self._append_rows(buf.getvalue().replace("nan", ""), n)

    def flush(self) -> None:
        """Everything written so far to the OS and on to the disk (fsync)."""
        if self._queued:
            text, n = "".join(self._queued), len(self._queued)
            self._queued = []
            self.rows -= n               # counted again once they are in the file
            self._append(text, n)
        self._sync()

    def _append_rows(self, text: str, n: int) -> None:
        if self._queued:                 # keep the order of single rows and blocks
            self.flush()
        self._append(text, n)
        if self._pending >= self.flush_every:
            self._sync()

    def _append(self, text: str, n: int) -> None:
        """Hand ``text`` (whole rows) to the OS; on failure cut the file back to the rows
        before it, so no row is ever half written."""
        data = text.encode("ascii")
        try:
            view = memoryview(data)
            while view:
                written = os.write(self._fd, view)
                view = view[written:]
        except OSError as exc:
            self._undo(exc)
        self._size += len(data)
        self.rows += n
        self._pending += n

    def _sync(self) -> None:
        try:
            os.fsync(self._fd)
        except OSError as exc:
            self._undo(exc)
        self._pending = 0
        self._synced_rows = self.rows

    def _undo(self, exc: OSError):
        try:
            os.ftruncate(self._fd, self._size)
        except OSError:
            pass
        raise LogError(f"cannot write {self.partial}: {exc.strerror or exc}; it keeps the "
                       f"{self.rows} rows written before") from None

    def close(self, complete: bool = True) -> Path:
        """Flush and close. A complete log is renamed to its final name; an incomplete one
        keeps the ``.partial`` suffix. Returns the path of the file on disk. A failed final
        write raises :class:`LogError` and leaves the ``.partial`` file."""
        if self._closed:
            return self.path if complete else self.partial
        try:
            self.flush()
        except LogError:
            self._release()
            raise
        self._release()
        if complete:
            os.replace(self.partial, self.path)
            return self.path
        return self.partial

    def _release(self) -> None:
        self._closed = True
        try:
            os.close(self._fd)
        except OSError:
            pass

    @property
    def closed(self) -> bool:
        return self._closed



def partial_path(path: str | Path) -> Path:
    """Where a writer streams ``path`` until it is complete."""
    path = Path(path)
    return path.with_name(path.name + PARTIAL_SUFFIX)


def open_log_writer(path: str | Path, meta: dict | None = None, optional: tuple[str, ...] = (),
                    overwrite: bool = True, **kwargs):
    """A :class:`LogWriter` or, for a ``.mcap`` file, a :class:`~delta6.link.mcaplog.McapLogWriter`
    (the same interface). ``overwrite=False`` refuses an existing file or ``.partial``."""
    if not overwrite:
        for existing in (Path(path), partial_path(path)):
            if existing.exists():
                raise LogError(f"{existing} exists (pass --force to replace it)")
    if Path(path).suffix.lower() == ".mcap":
        return mcaplog.McapLogWriter(path, meta, optional, **kwargs)
    return LogWriter(path, meta, optional, **kwargs)


def _six(values) -> list:
    if values is None:
        return [None] * 6
    values = list(values)
    if len(values) != 6:
        raise ValueError("theta and wrench take six values")
    return values



def _cell(value, column: str) -> str:
    if value is None:
        return ""
    if isinstance(value, (int, np.integer)) and column not in _TIME_COLUMNS:
        return str(int(value))
    value = float(value)
    if math.isnan(value):
        return ""
    fmt = _COLUMN_FORMATS.get(column, _FLOAT_FORMAT)
    return (_FLOAT_FORMAT if fmt == "%d" and not value.is_integer() else fmt) % value


# --- reading ------------------------------------------------------------------------------

#: Rows parsed at a time: reading never holds more than this many lines of text, so a log of
#: millions of rows costs little more than its arrays.
READ_CHUNK_ROWS = 100_000


def read_log(path: str | Path, *, require_complete_rows: bool = True) -> LogData:
    """Read a log, CSV or MCAP (told apart by the file's first bytes). Raises :class:`LogError`
    naming the problem: no file, wrong header, missing columns, unparsable or missing values (NaN), non-monotonic time.

    With ``require_complete_rows=False`` empty angle/wrench fields read as NaN (a stream that
    carried wrench only, or flagged samples) instead of being an error.
    """
    path = Path(path)
    if mcaplog.is_mcap(path):
        return mcaplog.read_mcap(path, require_complete_rows=require_complete_rows)
    try:
        cut = path.name.endswith(PARTIAL_SUFFIX) and not _ends_with_newline(path)
        # A spreadsheet's UTF-8 byte-order mark before the first line is no content; the rest
        # is ASCII either way.
        with open(path, "rb") as raw, io.TextIOWrapper(raw, encoding="ascii",
                                                       newline=None) as f:
            if raw.read(3) != BOM:
                raw.seek(0)
            meta, columns, body_start = _read_header(path, f)
            # Readers find columns by name: one the format does not know (a spreadsheet's note,
            # an index) is left out, whatever it holds, and named (LogData.ignored_columns).
            known = set(CORE_COLUMNS) | set(OPTIONAL_COLUMNS)
            keep = [i for i, c in enumerate(columns) if c in known]
            ignored = tuple(c for c in columns if c not in known)
            table, line_of = _read_body(path, f, len(columns), body_start, drop_last=cut,
                                        keep=keep, names=columns)
            columns = [columns[i] for i in keep]
        if cut:
            # What a killed writer left: its last row may be cut anywhere (a cut number is a
            # made-up number), so it is not read. A complete file always ends its rows.
            meta["cut_row_dropped"] = "1"
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        what = ("named .mcap but not an MCAP file (no MCAP magic)"
                if path.suffix.lower() == ".mcap" else "not a text CSV log (non-ASCII bytes)")
        raise LogError(f"{path}: {what}") from None
    except IsADirectoryError:
        raise LogError(f"{path}: cannot be read (Is a directory)") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot be read ({exc.strerror})") from None
    infinite = np.isinf(table).any(axis=1)
    if infinite.any():      # an empty field is a missing value; inf is never a measurement
        row = int(np.argmax(infinite))
        raise LogError(f"{path}: line {line_of[row]}: infinite value "
                       f"in column {columns[int(np.argmax(np.isinf(table[row])))]}")
    col = {name: table[:, i] for i, name in enumerate(columns)}

    t = col["t"]
    theta = np.stack([col[c] for c in THETA_COLUMNS], axis=1)
    wrench = np.stack([col[c] for c in WRENCH_COLUMNS], axis=1)
    if np.isnan(t).any():
        raise LogError(f"{path}: missing time value on line {line_of[int(np.argmax(np.isnan(t)))]}")
    check_rows(path, t, theta, wrench, lambda i: f"line {line_of[i]}", require_complete_rows)

    def optional(name):
        return col.get(name)

    return LogData(t=t, theta=theta, wrench=wrench, seq=int_column(optional("seq")),
                   status=int_column(optional("status")), host_t=optional("host_t"),
                   temp_c=optional("temp_c"), meta=meta, ignored_columns=ignored)


#: The UTF-8 byte-order mark spreadsheets write before a CSV file's first line.
BOM = b"\xef\xbb\xbf"


def _read_header(path: Path, f) -> tuple[dict, list[str], int]:
    """The comment lines and the column header: (meta, columns, index of the header line)."""
    meta: dict[str, str] = {}
    body_start = -1
    header = None
    for body_start, raw in enumerate(f):
        line = raw.rstrip("\r\n")
        if not line.startswith("#"):
            header = line
            break
        # A spreadsheet saving the file pads every line to the table's width with commas.
        content = line[1:].rstrip(",").strip()
        if content.startswith(MAGIC):
            for part in content.split()[1:]:
                if part.startswith("schema="):
                    meta["schema"] = part[len("schema="):]
        elif "=" in content and not content.startswith("units:"):
            key, _, value = content.partition("=")
            meta[key.strip()] = value.strip()
    if header is None:
        raise LogError(f"{path}: no column header line")
    if "schema" in meta and meta["schema"] != str(SCHEMA_VERSION):
        raise LogError(f"{path}: log schema {meta['schema']} is not supported "
                       f"(this version reads schema {SCHEMA_VERSION})")
    # Spreadsheets may quote the names.
    columns = [c.strip().strip('"') for c in header.split(",")]
    missing = [c for c in CORE_COLUMNS if c not in columns]
    if missing:
        raise LogError(f"{path}: missing column(s) {', '.join(missing)}")
    if len(set(columns)) != len(columns):
        raise LogError(f"{path}: duplicate column names")
    return meta, columns, body_start


def _read_body(path: Path, f, ncols: int, body_start: int, drop_last: bool = False,
               keep=None, names=None) -> tuple[np.ndarray, np.ndarray]:
    """The rows after the header, parsed a chunk at a time (blank lines skipped), and the file
    line (1-based) of each row: the columns ``keep`` (indices; default all) of ``ncols``,
    ``names`` naming them in errors. ``drop_last`` leaves out the last row (a cut one)."""
    keep = list(range(ncols)) if keep is None else list(keep)
    names = names or [str(i) for i in range(ncols)]
    parts, numbers = [], []
    number = body_start + 1           # the header's line number
    pending: tuple[str, int] | None = None
    while True:
        rows, lines = [], []
        for raw in f:
            number += 1
            line = raw.rstrip("\r\n")
            if not line.strip():
                continue
            if pending is not None:
                rows.append(pending[0])
                lines.append(pending[1])
            pending = (line, number)
            if len(rows) == READ_CHUNK_ROWS:
                break
        if not rows:
            break
        parts.append(_parse_rows(path, rows, ncols, lines, keep, names))
        numbers.append(np.asarray(lines, dtype=np.int64))
    if pending is not None and not drop_last:
        parts.append(_parse_rows(path, [pending[0]], ncols, [pending[1]], keep, names))
        numbers.append(np.asarray([pending[1]], dtype=np.int64))
    if not parts:
        raise LogError(f"{path}: no samples")
    if len(parts) == 1:
        return parts[0], numbers[0]
    return np.concatenate(parts, axis=0), np.concatenate(numbers)


def _ends_with_newline(path: Path) -> bool:
    with open(path, "rb") as f:
        f.seek(0, 2)
        if f.tell() == 0:
            return True
        f.seek(-1, 2)
        return f.read(1) == b"\n"



def _parse_rows(path: Path, rows: list[str], ncols: int, line_numbers: list[int],
                keep: list[int], names: list[str]) -> np.ndarray:
    for i, row in enumerate(rows):
        if row.count(",") != ncols - 1:
            raise LogError(f"{path}: line {line_numbers[i]} has {row.count(',') + 1} fields, "
                           f"expected {ncols}")
    text = "\n".join(rows)
    # comments=None: a '#' in a data row is damage to report, not a comment that hides fields
    try:  # fast path: every field present
        return np.loadtxt(io.StringIO(text), delimiter=",", dtype=float, ndmin=2,
                          comments=None, usecols=keep)
    except ValueError:
        pass
    # Empty fields (wrench-only streams, flagged samples) read as NaN; text that is not a
    # number is an error that names its line and column.
    for i, row in enumerate(rows):
        cells = row.split(",")
        for k in keep:
            cell = cells[k].strip()
            if cell:
                try:
                    float(cell)
                except ValueError:
                    raise LogError(f"{path}: line {line_numbers[i]}, column {names[k]}: "
                                   f"{cell[:20]!r} is not a number") from None
    return np.genfromtxt(io.StringIO(text), delimiter=",", dtype=float, ndmin=2,
                         missing_values="", filling_values=np.nan, comments=None,
                         usecols=keep)


