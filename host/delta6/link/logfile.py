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
from delta6.link.logdata import (  # noqa: F401 - re-exported: the log API is this module's
    CORE_COLUMNS,
    OPTIONAL_COLUMNS,
    PARTIAL_SUFFIX,
    SCHEMA_VERSION,
    THETA_COLUMNS,
    UNITS,
    WRENCH_COLUMNS,
    LogData,
    LogError,
)

MAGIC = "delta6-log"
_FLOAT_FORMAT = "%.9g"      # float32 values survive the round trip exactly


def header_lines(meta: dict, columns: tuple[str, ...]) -> list[str]:
    lines = [f"# {MAGIC} schema={SCHEMA_VERSION}"]
    for key, value in meta.items():
        text = str(value)
        if "\n" in text or "=" in key:
            raise ValueError(f"metadata {key!r} must be a single line without '=' in the key")
        lines.append(f"# {key}={text}")
    lines.append("# units: " + "; ".join(f"{k} {v}" for k, v in UNITS.items()))
    lines.append(",".join(columns))
    return lines


class LogWriter:
    """Write samples to ``path`` through ``path.partial``; rename on :meth:`close`.

    ``meta`` goes into the header as ``# key=value`` lines (conventionally ``design``,
    ``design_hash``, ``source``). ``optional`` picks the optional columns to write.
    ``flush_every`` rows are forced to disk at a time (fsync); blocks are handed to the
    operating system as they are written, so only a power cut can lose the rows since.
    Use as a context manager: a clean exit renames the file, an exception still closes and
    renames it (nothing received is lost) unless ``keep_partial_on_error`` is set.
    """

    def __init__(self, path: str | Path, meta: dict | None = None,
                 optional: tuple[str, ...] = (), flush_every: int = 256,
                 keep_partial_on_error: bool = False):
        unknown = set(optional) - set(OPTIONAL_COLUMNS)
        if unknown:
            raise ValueError(f"unknown optional columns {sorted(unknown)}")
        self.path = Path(path)
        self.partial = self.path.with_name(self.path.name + PARTIAL_SUFFIX)
        self.columns = CORE_COLUMNS + tuple(c for c in OPTIONAL_COLUMNS if c in optional)
        self.flush_every = max(1, flush_every)
        self.keep_partial_on_error = keep_partial_on_error
        self.rows = 0
        self._pending = 0
        try:
            self._file = open(self.partial, "w", encoding="ascii", newline="\n")
        except OSError as exc:
            raise LogError(f"cannot create {self.partial}: {exc.strerror}") from None
        self._file.write("\n".join(header_lines(dict(meta or {}), self.columns)) + "\n")
        self._file.flush()

    # -- writing ---------------------------------------------------------------------------

    def write(self, t: float, theta, wrench, **optional) -> None:
        """One sample. ``theta`` or ``wrench`` may be None (written as empty fields)."""
        values = [t, *(_six(theta)), *(_six(wrench))]
        values += [optional.get(c) for c in self.columns[len(CORE_COLUMNS):]]
        self._file.write(",".join(_cell(v) for v in values) + "\n")
        self.rows += 1
        self._pending += 1
        if self._pending >= self.flush_every:
            self.flush()

    def write_block(self, t: np.ndarray, theta: np.ndarray, wrench: np.ndarray,
                    **optional: np.ndarray) -> None:
        """Many samples at once (vectorised formatting, for the simulator and the decoder)."""
        n = len(t)
        cols = [np.asarray(t, float)[:, None], _block(theta, n), _block(wrench, n)]
        for name in self.columns[len(CORE_COLUMNS):]:
            value = optional.get(name)
            cols.append(np.full((n, 1), np.nan) if value is None
                        else np.asarray(value, float).reshape(n, 1))
        table = np.hstack(cols)
        buf = io.StringIO()
        np.savetxt(buf, table, fmt=_FLOAT_FORMAT, delimiter=",")
        text = buf.getvalue().replace("nan", "")
        self._file.write(text)
        self.rows += n
        self._pending += n
        if self._pending >= self.flush_every:
            self.flush()
        else:
            self._file.flush()     # to the OS: a crash of this process loses none of it

    def flush(self) -> None:
        """Everything written so far to the OS and on to the disk (fsync)."""
        self._file.flush()
        os.fsync(self._file.fileno())
        self._pending = 0

    def close(self, complete: bool = True) -> Path:
        """Flush and close. A complete log is renamed to its final name; an incomplete one
        keeps the ``.partial`` suffix. Returns the path of the file on disk."""
        if self._file.closed:
            return self.path if complete else self.partial
        self.flush()
        self._file.close()
        if complete:
            os.replace(self.partial, self.path)
            return self.path
        return self.partial

    def __enter__(self) -> "LogWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(complete=exc_type is None or not self.keep_partial_on_error)


def open_log_writer(path: str | Path, meta: dict | None = None, optional: tuple[str, ...] = (),
                    **kwargs):
    """A :class:`LogWriter` or, for a ``.mcap`` file, a :class:`~delta6.link.mcaplog.McapLogWriter`
    (the same interface)."""
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


def _block(values, n: int) -> np.ndarray:
    if values is None:
        return np.full((n, 6), np.nan)
    values = np.asarray(values, dtype=float)
    if values.shape != (n, 6):
        raise ValueError(f"expected ({n}, 6) values, got {values.shape}")
    return values


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    value = float(value)
    return "" if math.isnan(value) else _FLOAT_FORMAT % value


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
        with open(path, encoding="ascii", newline=None) as f:
            meta, columns, body_start = _read_header(path, f)
            table = _read_body(path, f, len(columns), body_start)
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise LogError(f"{path}: not a text CSV log (non-ASCII bytes)") from None
    except IsADirectoryError:
        raise LogError(f"{path}: cannot be read (Is a directory)") from None
    except OSError as exc:
        raise LogError(f"{path}: cannot be read ({exc.strerror})") from None
    col = {name: table[:, i] for i, name in enumerate(columns)}

    t = col["t"]
    theta = np.stack([col[c] for c in THETA_COLUMNS], axis=1)
    wrench = np.stack([col[c] for c in WRENCH_COLUMNS], axis=1)
    if np.isnan(t).any():
        raise LogError(f"{path}: missing time value on line {_first_nan_line(t, body_start)}")
    if require_complete_rows:
        for name, values in (("theta_e", theta), ("wrench", wrench)):
            bad = np.isnan(values).any(axis=1)
            if bad.any():
                raise LogError(f"{path}: missing or NaN {name} value on line "
                               f"{_first_nan_line(bad, body_start)}")
    if not np.all(np.isfinite(t)):
        raise LogError(f"{path}: non-finite time value")
    steps = np.diff(t)
    if (steps <= 0).any():
        line = int(np.argmax(steps <= 0)) + body_start + 3
        raise LogError(f"{path}: time is not strictly increasing at line {line}")

    def optional(name):
        return col.get(name)

    return LogData(t=t, theta=theta, wrench=wrench, seq=_as_int(optional("seq")),
                   status=_as_int(optional("status")), host_t=optional("host_t"),
                   temp_c=optional("temp_c"), meta=meta)


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
        content = line[1:].strip()
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
    columns = [c.strip() for c in header.split(",")]
    missing = [c for c in CORE_COLUMNS if c not in columns]
    if missing:
        raise LogError(f"{path}: missing column(s) {', '.join(missing)}")
    if len(set(columns)) != len(columns):
        raise LogError(f"{path}: duplicate column names")
    return meta, columns, body_start


def _read_body(path: Path, f, ncols: int, body_start: int) -> np.ndarray:
    """The rows after the header, parsed a chunk at a time (blank lines skipped)."""
    parts = []
    done = 0
    while True:
        rows = []
        for raw in f:
            line = raw.rstrip("\r\n")
            if line.strip():
                rows.append(line)
                if len(rows) == READ_CHUNK_ROWS:
                    break
        if not rows:
            break
        parts.append(_parse_rows(path, rows, ncols, body_start + 2 + done))
        done += len(rows)
        if len(rows) < READ_CHUNK_ROWS:
            break
    if not parts:
        raise LogError(f"{path}: no samples")
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=0)


def _as_int(values: np.ndarray | None) -> np.ndarray | None:
    """Integer columns as int64 when complete; left as float (with NaN gaps) otherwise."""
    if values is None or np.isnan(values).any():
        return values
    return values.astype(np.int64)


def _parse_rows(path: Path, rows: list[str], ncols: int, first_line: int) -> np.ndarray:
    for i, row in enumerate(rows):
        if row.count(",") != ncols - 1:
            raise LogError(f"{path}: line {first_line + i} has {row.count(',') + 1} fields, "
                           f"expected {ncols}")
    text = "\n".join(rows)
    try:  # fast path: every field present
        return np.loadtxt(io.StringIO(text), delimiter=",", dtype=float, ndmin=2)
    except ValueError:
        pass
    # Empty fields (wrench-only streams, flagged samples) read as NaN; text that is not a
    # number is an error that names its line.
    table = np.genfromtxt(io.StringIO(text), delimiter=",", dtype=float, ndmin=2,
                          missing_values="", filling_values=np.nan)
    for i, row in enumerate(rows):
        for cell in row.split(","):
            cell = cell.strip()
            if cell:
                try:
                    float(cell)
                except ValueError:
                    raise LogError(f"{path}: line {first_line + i}: {cell[:20]!r} is not a "
                                   "number") from None
    return table


def _first_nan_line(mask_or_values: np.ndarray, body_start: int) -> int:
    mask = np.isnan(mask_or_values) if mask_or_values.dtype != bool else mask_or_values
    return int(np.argmax(mask)) + body_start + 2


