"""Getting a simulated run out: the log file (also the replay file of the virtual board) and a
real-time stream of encoder angles for driving a virtual board live."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Iterator, NamedTuple

import numpy as np

from delta6.link.logfile import open_log_writer
from delta6.link.protocol import theta_to_counts
from delta6.twin.truth import truth_path, write_truth

#: Rows per write (and per progress report).
WRITE_BLOCK = 10_000


class EncoderSample(NamedTuple):
    t: float               # sample time of the run, s
    theta: np.ndarray      # (6,) encoder angles, rad


def write_log(result, path: str | Path, *, progress: Callable[[float], None] | None = None,
              extra_meta: dict | None = None) -> tuple[Path, Path]:
    """Write the run as a log (``docs/log-format.md``) and its truth file next to it
    (``data.csv`` -> ``data.truth.json``). The log, with its ``t`` and ``theta_e1..6``
    columns, is also the replay file of the virtual board. Returns both paths."""
    truth = result.truth
    meta = {"design": result.design.name, "design_hash": truth["design"]["hash"],
            "source": "delta6 simulate (digital twin)", "seed": truth["seed"],
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


def iter_realtime(source, *, speed: float = 1.0, loop: bool = False,
                  clock: Callable[[], float] = time.monotonic,
                  sleep: Callable[[float], None] = time.sleep) -> Iterator[EncoderSample]:
    """Yield the encoder samples of ``source`` (a ``SimResult`` or a ``LogData`` read back from
    a log: anything with ``t`` and ``theta``) at the pace of their time stamps, ``speed`` times
    real time. A consumer that falls behind gets the samples late, never skipped. ``loop``
    starts over at the end (time keeps increasing by one run length)."""
    if not speed > 0:
        raise ValueError("speed must be positive")
    t = np.asarray(source.t, dtype=float)
    theta = np.asarray(source.theta, dtype=float)
    if len(t) == 0:
        return
    period = (t[-1] - t[0]) + (t[-1] - t[-2] if len(t) > 1 else 0.0)
    start = clock()
    lap = 0
    while True:
        for ti, row in zip(t, theta):
            run_time = ti - t[0] + lap * period
            wait = start + run_time / speed - clock()
            if wait > 0:
                sleep(wait)
            yield EncoderSample(float(ti + lap * period), row.copy())
        if not loop:
            return
        lap += 1


class EncoderTrack:
    """A run's encoder angles as a function of time, held between samples (zero-order hold),
    for consumers that sample at their own times: ``angles(t_s)`` (s from the run's start,
    any shape (M,)) -> (M, 6) rad. This is the ``motion`` interface of
    ``delta6.sim.simdevice.SimulatedDevice``: ``SimulatedDevice(motion=EncoderTrack(result))`` runs
    the firmware core on the twin's encoder angles. ``loop`` repeats the run; otherwise the last
    sample holds."""

    def __init__(self, source, loop: bool = False):
        self.t = np.asarray(source.t, dtype=float) - float(source.t[0])
        self.theta = np.asarray(source.theta, dtype=float)
        self.loop = loop
        self.period = self.t[-1] + (self.t[-1] - self.t[-2] if len(self.t) > 1 else 1.0)

    def angles(self, t_s) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        if self.loop:
            t = np.mod(t, self.period)
        # A nanosecond of slack: a time computed to be a sample's (from microseconds, or a
        # lap later) may land a rounding error before it.
        index = np.clip(np.searchsorted(self.t, t + 1e-9, side="right") - 1, 0, len(self.t) - 1)
        return self.theta[index]


def to_counts(theta: np.ndarray, zero: int | np.ndarray = 0) -> np.ndarray:
    """Encoder angles (rad) as the raw absolute counts an encoder would report, given the count
    at zero deflection (``zero``): what a virtual board's encoder model serves
    (:func:`delta6.link.protocol.theta_to_counts`)."""
    return theta_to_counts(theta, zero)
