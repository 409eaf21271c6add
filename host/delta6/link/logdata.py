"""What every log format shares (``docs/log-format.md``): the columns, the rows read back as
arrays (:class:`LogData`) and the error that names a problem. The formats are
:mod:`delta6.link.logfile` (CSV, and the front door: ``read_log``, ``open_log_writer``) and
:mod:`delta6.link.mcaplog` (MCAP with ROS 2 messages)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from delta6.core.errors import UserError

SCHEMA_VERSION = 1
THETA_COLUMNS = tuple(f"theta_e{i}" for i in range(1, 7))
WRENCH_COLUMNS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: Required, in this order, at the start of every row.
CORE_COLUMNS = ("t",) + THETA_COLUMNS + WRENCH_COLUMNS
#: Optional columns, after the core ones, in this order when present.
OPTIONAL_COLUMNS = ("seq", "status", "host_t", "temp_c")
UNITS = {"t": "s", "theta_e": "rad", "F": "N", "M": "N*m", "host_t": "s (host monotonic)",
         "temp_c": "degC", "status": "status word (docs/protocol.md)", "seq": "record sequence"}
PARTIAL_SUFFIX = ".partial"


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

    def __len__(self) -> int:
        return len(self.t)
