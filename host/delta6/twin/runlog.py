"""A simulated run as files: the log (``docs/log-format.md``; also the replay file of the
virtual board) and the truth file beside it."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from delta6.link.logfile import open_log_writer
from delta6.twin.truth import truth_path, write_truth

#: Rows per write (and per progress report).
WRITE_BLOCK = 10_000


def write_log(result, path: str | Path, *, progress: Callable[[float], None] | None = None,
              extra_meta: dict | None = None) -> tuple[Path, Path]:
    """Write the run as a log (``docs/log-format.md``) and its truth file next to it
    (``data.csv`` -> ``data.truth.json``). The log, with its ``t`` and ``theta_e1..6``
    columns, is also the replay file of the virtual board. Returns both paths."""
    truth = result.truth
    meta = {"design": result.design.name, "design_hash": truth["design"]["hash"],
            "source": "delta6 simulate (digital twin)", "wrench_source": "reference",
            "seed": truth["seed"],
            "rate_hz": f"{truth['rate_hz']:g}", "truth": truth_path(path).name,
            **(extra_meta or {})}
    if truth.get("scenario"):
        meta["scenario"] = truth["scenario"]
    optional = ("temp_c",) if result.temp_c is not None else ()
    n = len(result)
    with open_log_writer(path, meta, optional=optional) as log:
        for start in range(0, n, WRITE_BLOCK):
            part = slice(start, min(n, start + WRITE_BLOCK))
            extra = {"temp_c": result.temp_c[part]} if result.temp_c is not None else {}
            log.write_block(result.t[part], result.theta[part], result.wrench[part], **extra)
            if progress:
                progress(part.stop / n)
    return Path(path), write_truth(truth_path(path), truth)
