"""What every log format shares (``docs/log-format.md``): the columns, the rows read back as
arrays (:class:`LogData`) and the error that names a problem. The formats are
:mod:`delta6.link.logfile` (CSV, and the front door: ``read_log``, ``open_log_writer``) and
:mod:`delta6.link.mcaplog` (MCAP with ROS 2 messages)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from delta6.core.errors import UserError

SCHEMA_VERSION = 1
THETA_COLUMNS = tuple(f"theta_e{i}" for i in range(1, 7))
WRENCH_COLUMNS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: Required, in this order, at the start of every row.
CORE_COLUMNS = ("t",) + THETA_COLUMNS + WRENCH_COLUMNS
#: The columns every row of a complete log fills.
COMPLETE_COLUMNS = THETA_COLUMNS + WRENCH_COLUMNS
#: Optional columns, after the core ones, in this order when present.
OPTIONAL_COLUMNS = ("seq", "status", "host_t", "temp_c")
UNITS = {"t": "s", "theta_e": "rad", "F": "N", "M": "N*m", "host_t": "s (host monotonic)",
         "temp_c": "degC", "status": "status word (docs/protocol.md)", "seq": "record sequence"}
PARTIAL_SUFFIX = ".partial"
#: Rows a log writer hands to the OS (and fsyncs) at a time, whichever its format.
FLUSH_EVERY = 256


def meta_text(value) -> str:
    """A header value as one line of printable ASCII: anything else (a name with a newline or
    non-ASCII letters that slipped past the checks) is written escaped, never refused."""
    text = str(value)
    if text.isascii() and text.isprintable():
        return text
    return text.encode("unicode_escape").decode("ascii")


class LogError(UserError):
    """A log file is missing, malformed or unusable; the message names the problem."""


@dataclass
class LogData:
    """A log read back into arrays. ``theta`` and ``wrench`` are (N, 6); optional columns
    are None when the file lacks them."""

    t: np.ndarray
    theta: np.ndarray
    wrench: np.ndarray
    seq: np.ndarray | None = None
    status: np.ndarray | None = None
    host_t: np.ndarray | None = None
    temp_c: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    ignored_columns: tuple = ()     # columns of the file the log format does not know

    def __len__(self) -> int:
        return len(self.t)

    def every(self, k: int) -> LogData:
        """Every ``k``-th row: the log as if it had been recorded at 1/k of its rate."""
        if k == 1:
            return self

        def thin(a):
            return None if a is None else a[::k]

        return replace(self, t=self.t[::k], theta=self.theta[::k], wrench=self.wrench[::k],
                       seq=thin(self.seq), status=thin(self.status), host_t=thin(self.host_t),
                       temp_c=thin(self.temp_c))


def wrench_from_device(meta: dict) -> bool:
    """Whether a log's wrench is the device's own model output (``wrench_source=device``; logs
    written before the key existed: those that carry the device's ``firmware`` version), not a
    reference sensor's. Fitting or diagnosing the model against it compares it with itself."""
    source = meta.get("wrench_source")
    return source == "device" or (source is None and "firmware" in meta)


def unchecked_design_notes(meta: dict, design_path) -> list[str]:
    """A note when a log names no design hash: nothing tells whether ``design_path`` is the
    mechanism it came from (a wrong one gives a plausible, wrong table)."""
    if meta.get("design_hash") or meta.get("design"):
        return []
    return [f"note: the log names no design in its header: it was not checked against "
            f"{design_path}"]


def require_reference_wrench(meta: dict, name, purpose: str) -> None:
    """Refuse a device log where a reference wrench is needed: ``purpose`` says why (e.g.
    "an evaluation compares estimators with a reference")."""
    if wrench_from_device(meta):
        raise UserError(f"{name}: the wrench in this log is the device's own model output "
                        f"(a device log), not a reference sensor's: {purpose}")


def six_columns(values, n: int) -> np.ndarray:
    """``values`` as an (n, 6) float array; None is a block of missing values (NaN)."""
    if values is None:
        return np.full((n, 6), np.nan)
    values = np.asarray(values, dtype=float)
    if values.shape != (n, 6):
        raise ValueError(f"expected ({n}, 6) values, got {values.shape}")
    return values


def check_rows(path, t: np.ndarray, theta: np.ndarray, wrench: np.ndarray,
               place, require_complete_rows: bool) -> None:
    """The row checks both log readers share: complete angle and wrench rows (when required)
    and strictly increasing time. ``place(i)`` names row i in the reader's terms ("line 7" of
    a CSV file, "sample 3" of an MCAP file) for the one-line error."""
    if require_complete_rows:
        # The first row in the file's order, whichever column it is in (no copy of a long
        # log's columns: one flag per row of each).
        rows = [np.isnan(values).any(axis=1) for values in (theta, wrench)]
        if rows[0].any() or rows[1].any():
            row = min(int(np.argmax(r)) if r.any() else len(r) for r in rows)
            values = np.concatenate([theta[row], wrench[row]])
            name = COMPLETE_COLUMNS[int(np.argmax(np.isnan(values)))]
            count = int((rows[0] | rows[1]).sum())
            raise LogError(f"{path}: missing or NaN {name} value at {place(row)} ({count} "
                           f"incomplete row{'s' if count > 1 else ''}: failed reads? `delta6 "
                           "convert IN OUT --complete-rows` keeps the complete ones)")
    steps = np.diff(t)
    if (steps <= 0).any():
        at = int(np.argmax(steps <= 0))
        what = ("a row repeats the time of the one before (a duplicated row?)" if steps[at] == 0
                else "time goes back (rows out of order?)")
        raise LogError(f"{path}: time is not strictly increasing at {place(at + 1)}: {what}")


class PartialOnError:
    """The ``with`` behaviour both log writers share: a clean exit completes the log; an
    exception leaves the ``.partial`` file (unless ``keep_partial_on_error`` is False), and a
    failure to close is raised only when nothing else went wrong."""

    keep_partial_on_error = True

    def close(self, complete: bool = True):   # pragma: no cover - the writers define it
        raise NotImplementedError

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            self.close(complete=exc_type is None or not self.keep_partial_on_error)
        except LogError:
            if exc_type is None:
                raise


def int_column(values: np.ndarray | None) -> np.ndarray | None:
    """An integer column (seq, status) as int64 when complete; left as float (with NaN gaps)
    otherwise."""
    if values is None or np.isnan(values).any():
        return values
    return values.astype(np.int64)
