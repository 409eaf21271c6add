"""Helpers for the virtual-board tests: the harness's encoder read log, and pairing each
streamed sample with the scan that latched it."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.build.avrbuild import NANO

F_CPU = NANO.f_cpu           # the clock the virtual board emulates


@dataclass
class Reads:
    """One row per encoder scan, as the emulated sensors served it."""

    cycle: np.ndarray      # (n,) cycle at which the chip selects fell (the latch)
    counts: np.ndarray     # (n, 6) counts served
    faults: np.ndarray     # (n, 6) fault kind per encoder (0 none, 1 biterror, 2 weak, ...)
    complete: np.ndarray   # (n,) bit j: encoder j's frame was clocked out completely

    @property
    def fault_mask(self) -> np.ndarray:
        return ((self.faults != 0) << np.arange(6)).sum(axis=1)


def read_reads(path: Path) -> Reads:
    rows = np.loadtxt(path, dtype=np.int64, ndmin=2)
    return Reads(rows[:, 0], rows[:, 1:7], rows[:, 7:13], rows[:, 13])


def pair(t_us: np.ndarray, reads: Reads, period_us: float) -> np.ndarray:
    """Index of the scan behind each sample: the firmware stamps a sample with micros() at its
    latch, and micros() runs a fixed offset (< one period) behind the cycle counter. Checks
    that every sample has its scan within 50 us of the common offset."""
    read_us = reads.cycle / (F_CPU / 1e6)
    idx = np.clip(np.searchsorted(read_us, t_us), 1, len(read_us) - 1)
    nearest = np.where(np.abs(read_us[idx - 1] - t_us) < np.abs(read_us[idx] - t_us), idx - 1, idx)
    offset = float(np.median(read_us[nearest] - t_us))
    assert 0 <= offset < period_us / 2, offset
    target = t_us + offset
    idx = np.clip(np.searchsorted(read_us, target), 1, len(read_us) - 1)
    nearest = np.where(np.abs(read_us[idx - 1] - target) < np.abs(read_us[idx] - target),
                       idx - 1, idx)
    residual = np.abs(read_us[nearest] - target)
    assert residual.max() < 50, residual.max()
    assert len(np.unique(nearest)) == len(nearest), "two samples claim the same scan"
    return nearest


def wait_board_time(live, t: float, timeout: float = 60.0) -> None:
    """Wait until the board's clock passes ``t`` seconds."""
    deadline = time.monotonic() + timeout
    while live.time() < t:
        assert time.monotonic() < deadline, f"the board did not reach {t} s"
        time.sleep(0.02)


def drain(dev, until_t: float, timeout: float = 60.0) -> list:
    """Samples from ``dev`` until one with device time >= until_t (s) arrives."""
    out = []
    deadline = time.monotonic() + timeout
    while not out or out[-1].t < until_t:
        assert time.monotonic() < deadline, "the stream stopped"
        out.append(dev.get(timeout=10))
    return out
