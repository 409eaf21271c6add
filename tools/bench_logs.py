"""Write and read speed of the two log formats (CSV and MCAP with ROS 2 messages), per row.

    .venv/bin/python tools/bench_logs.py [--rows N]

Rows as a device log with angles (wrench+raw mode) has them: t, six angles, six wrench values,
seq, status, host_t; written in blocks of 1000 rows, read back with ``read_log``.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from delta6.link.logfile import open_log_writer, read_log


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=100_000)
    n = parser.parse_args().rows
    rng = np.random.default_rng(0)
    t = np.arange(n) / 250 + 0.004
    theta = np.round(rng.normal(size=(n, 6)) * 0.05 / 3.835e-4) * 3.835e-4
    wrench = np.round(rng.normal(size=(n, 6)) * 3, 3)
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("run.csv", "run.mcap"):
            path = Path(tmp) / name
            started = time.perf_counter()
            with open_log_writer(path, {"design": "delta6"},
                                 optional=("seq", "status", "host_t")) as log:
                for i in range(0, n, 1000):
                    part = slice(i, i + 1000)
                    log.write_block(t[part], theta[part], wrench[part], seq=np.arange(n)[part],
                                    status=np.zeros(n, int)[part], host_t=t[part] + 0.01)
            written = time.perf_counter() - started
            started = time.perf_counter()
            back = read_log(path)
            read = time.perf_counter() - started
            assert len(back) == n
            print(f"{name:9s} {n} rows: write {written / n * 1e6:5.1f} us/row, read "
                  f"{read / n * 1e6:5.1f} us/row, {os.path.getsize(path) / n:5.0f} bytes/row")


if __name__ == "__main__":
    main()
