"""A log's motion streamed through the firmware on the virtual board, each record paired with
the log row whose angles the emulated encoders served: the on-board estimate, scored against
the log's reference wrench like any estimator, and the raw counts, to run the host's model on
exactly what the board saw.

The replay starts with ``hold_s`` seconds at the log's first pose: the stream starts inside
that hold, so the board's history (the calibrated model's plays and speed filter) is settled at
that pose when the first record goes out, as a host model started on the first record is.
"""
from __future__ import annotations

import dataclasses
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.core.errors import UserError
from delta6.link import protocol as P
from delta6.link.device import Device
from delta6.sim.virtualboard import VirtualBoard, write_replay


@dataclass
class BoardRun:
    t: np.ndarray            # (m,) device time of each record, s
    counts: np.ndarray       # (m, 6) raw counts the board latched
    delta: np.ndarray        # (m, 6) signed counts from the zero (what the board solved)
    wrench: np.ndarray       # (m, 6) the board's wrench
    status: np.ndarray       # (m,) status words
    rows: np.ndarray         # (m,) log row whose angles the encoders served (-1: the hold)
    matched: float           # share of motion records whose counts equal their row's
    stats: dict              # the virtual board's timing statistics
    rate_hz: int
    info: object             # the board's INFO record (design, calibration, scaling)


def _pair(t_dev, counts, t_replay, served) -> tuple[np.ndarray, float]:
    """Replay row of every record: the device clock runs from the firmware's start, the replay
    from the emulator's; the offset (a few ms of boot) is the one that matches the counts."""
    best = None
    for offset in np.arange(-0.03, 0.03, 2.5e-4):
        rows = np.searchsorted(t_replay, t_dev - offset, side="right") - 1
        rows = np.clip(rows, 0, len(t_replay) - 1)
        score = float(np.mean(np.all(served[rows] == counts, axis=1)))
        if best is None or score > best[0]:
            best = (score, rows)
    return best[1], best[0]


#: Attempts at starting the stream inside the initial hold: the emulator runs as fast as it
#: can while the host sets the board up, so on a loaded machine the hold may be over before
#: START arrives; each retry doubles the hold.
START_ATTEMPTS = 3


def stream_log(image, log, *, rate_hz: int = 250, zero=0, hold_s: float = 3.0,
               seconds: float | None = None, speed: float = 0.0, faults=(),
               progress=None) -> BoardRun:
    """Replay ``log`` (``t``, ``theta``) on the virtual board running ``image`` and record
    its wrench+raw stream at ``rate_hz`` for the log's duration (or ``seconds``); ``faults``:
    the virtual board's encoder faults, their times counted from the log's start."""
    for attempt in range(START_ATTEMPTS):
        shifted = [dataclasses.replace(f, start=f.start + hold_s * 2 ** attempt,
                                       stop=f.stop + hold_s * 2 ** attempt) for f in faults]
        run = _stream_once(image, log, rate_hz=rate_hz, zero=zero,
                           hold_s=hold_s * 2 ** attempt, seconds=seconds, speed=speed,
                           faults=shifted, progress=progress)
        if run is not None:
            return run
        if progress:
            progress("the stream started after the replay's initial hold: again, holding longer")
    raise UserError(f"the stream did not start inside the replay's initial hold "
                    f"({hold_s * 2 ** (START_ATTEMPTS - 1):g} s at the last of "
                    f"{START_ATTEMPTS} attempts): the machine is too busy")


def _stream_once(image, log, *, rate_hz, zero, hold_s, seconds, speed, faults,
                 progress) -> BoardRun | None:
    """One replay; None when the stream started after the initial hold."""
    t_log = np.asarray(log.t, dtype=float) - float(log.t[0])
    duration = float(t_log[-1]) if seconds is None else min(float(seconds), float(t_log[-1]))
    served_log = P.theta_to_counts(log.theta, zero).astype(np.int64)
    t_replay = np.concatenate([[0.0], t_log + hold_s])
    served = np.concatenate([served_log[:1], served_log])
    with tempfile.TemporaryDirectory(prefix="delta6-boardstream-") as tmp:
        replay = write_replay(Path(tmp) / "run.d6rp", t_replay, served)
        board = VirtualBoard(image=image, replay=replay, zero=zero, speed=speed, faults=faults)
        with board:
            with Device(board.port) as dev:
                if np.any(np.asarray(zero) != 0):
                    dev.set_zero(np.broadcast_to(zero, (6,)))
                dev.set_mode("raw")
                info = dev.info(refresh=True)
                dev.start(rate_hz)
                samples, end = [], hold_s + duration
                last_note = time.monotonic()
                while not samples or samples[-1].t < end:
                    samples.append(dev.get(timeout=30))
                    if progress and time.monotonic() - last_note > 10:
                        progress(f"board time {samples[-1].t:.0f} of {end:.0f} s")
                        last_note = time.monotonic()
                dev.stop()
            board.stop()
            stats = board.stats()
    t_dev = np.array([s.t for s in samples])
    counts = np.array([s.counts for s in samples], dtype=np.int64)
    wrench = np.array([s.wrench for s in samples], dtype=float)
    status = np.array([s.status for s in samples], dtype=np.int64)
    if t_dev[0] > hold_s - 0.5:
        return None
    if not np.all(counts[0] == served[0]):
        raise UserError("the board's first counts are not the replay's first pose: "
                        f"{counts[0].tolist()} against {served[0].tolist()} (zero offset?)")
    rows, _ = _pair(t_dev, counts, t_replay, served)
    moving = rows > 0
    matched = float(np.mean(np.all(served[rows[moving]] == counts[moving], axis=1)))
    return BoardRun(t=t_dev, counts=counts, delta=P.count_delta(counts, zero), wrench=wrench,
                    status=status, rows=rows - 1, matched=matched, stats=stats,
                    rate_hz=rate_hz, info=info)
