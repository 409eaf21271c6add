"""``delta6 log``: record the stream to a log file (docs/log-format.md), safely: CSV, or MCAP
with ROS 2 messages when the file name ends in ``.mcap``.

Rows go to FILE.partial and are handed to the operating system as they come; the file is
renamed to FILE when the log closes: at the end of --duration, on Ctrl-C, SIGTERM or SIGHUP,
and also when the port disappears or the device restarts (the message says so and the exit
status is 2). Nothing received is lost. A full disk ends the log with FILE.partial holding every
row up to the failed write (docs/reliability.md).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from delta6.commands._port import (
    Progress,
    add_port_arguments,
    add_stream_arguments,
    flagged,
    frame_id,
    log_meta,
    next_block,
    number,
    open_device,
    start_stream,
)
from delta6.commands._signals import stop_requests
from delta6.core.errors import UserError
from delta6.core.outputs import check_output_file
from delta6.link.device import DeviceError
from delta6.link.logfile import LogError, LogWriter, open_log_writer
from delta6.link.ros2msg import DEFAULT_FRAME_ID

NAME = "log"
HELP = ("record the wrench stream to a log, CSV or MCAP (progress shown; Ctrl-C, SIGTERM or "
        "SIGHUP end it cleanly)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="FILE",
                        help="log file: CSV, or MCAP with ROS 2 messages when it ends in .mcap")
    parser.add_argument("--frame-id", type=frame_id, default=DEFAULT_FRAME_ID, metavar="ID",
                        help=f"frame id of the wrench messages (default {DEFAULT_FRAME_ID})")
    parser.add_argument("--duration", type=number("--duration", low=0, low_open=True), metavar="S",
                        help="seconds to record (default: until Ctrl-C)")
    add_stream_arguments(parser)
    parser.add_argument("--capture", metavar="FILE.bin",
                        help="also keep every received byte in this new file (delta6 decode "
                             "reads it)")
    parser.add_argument("--force", action="store_true",
                        help="replace an existing FILE, FILE.partial or capture")


class Stats:
    """Rate, loss and fault figures of a log being written (its rows: ``writer.rows``)."""

    def __init__(self, writer: LogWriter):
        self.writer = writer
        self.first_t = self.last_t = None
        self.first_seq = self.last_seq = None
        self.flagged = 0

    @property
    def rows(self) -> int:
        return self.writer.rows

    def add(self, block) -> None:
        if self.first_t is None:
            self.first_t, self.first_seq = block.t[0], int(block.seq[0])
        self.last_t, self.last_seq = block.t[-1], int(block.seq[-1])
        self.flagged += flagged(block.status)

    def rate(self) -> float:
        span = (self.last_t - self.first_t) if self.rows > 1 else 0.0
        return (self.rows - 1) / span if span > 0 else 0.0

    def summary(self, health) -> str:
        if not self.rows:
            return "no samples received"
        expected = self.last_seq - self.first_seq + 1
        missing = expected - self.rows
        return (f"{self.rows} samples over {self.last_t - self.first_t:.3f} s device time, "
                f"{self.rate():.1f} Hz; {missing} of {expected} missing "
                f"({100 * missing / expected:.3g} %) in {health.sequence_gaps} gaps; "
                f"{self.flagged} flagged; " + health.link_summary())


class DeviceRestarted(DeviceError):
    """The device rebooted mid-log: its clock and sequence start again."""


def _write(stats: Stats, block, session: list) -> None:
    """Append a block; a device that restarted (a new session, or time not increasing) ends
    the log there, as a log's time must increase and the samples after a reboot belong to a
    new one. ``session`` holds the log's session once the first block set it."""
    if block.session is not None and len(block):
        if not session:
            session.append(int(block.session[0]))
        other = np.flatnonzero(block.session != session[0])
        if other.size:
            if other[0]:
                _write(stats, block.head(int(other[0])), session)
            raise DeviceRestarted("the device restarted during the log (its counters began "
                                  "again)")
    t = np.concatenate(([stats.last_t], block.t)) if stats.rows else block.t
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        keep = int(back[0]) + (0 if stats.rows else 1)
        if keep:
            _write(stats, block.head(keep), session)
        raise DeviceRestarted("the device restarted during the log (its clock went back)")
    stats.writer.write_block(block.t, block.theta, block.wrench, seq=block.seq,
                             status=block.status, host_t=block.host_t)
    stats.add(block)


def _drain(dev, stats: Stats, session: list) -> None:
    """Write what was received but not yet read: the log keeps every sample that arrived."""
    while True:
        try:
            _write(stats, dev.read_block(timeout=0.0), session)
        except DeviceError:
            return


def _check_outputs(args: argparse.Namespace) -> None:
    check_output_file(args.output, "-o", force=args.force, partial=True)
    if args.capture is not None:
        if os.path.abspath(args.capture) == os.path.abspath(args.output):
            raise UserError("--capture and -o name the same file")
        check_output_file(args.capture, "--capture", force=args.force)
        if args.force and os.path.isfile(args.capture):
            os.remove(args.capture)


def _record(dev, args: argparse.Namespace, stop):
    """Stream into the log until the duration, a stop signal or a device error; close the log
    (whole, or as .partial after a write failure). Returns (path, stats, health, ending,
    unstopped): ``unstopped`` says why the stream may not have stopped ("" when it did)."""
    progress = Progress()
    ending: UserError | None = None
    unstopped = ""                  # why the stream may not have stopped
    cut = False                     # a second stop signal ended the streaming loop
    rate = start_stream(dev, args)
    info = dev.info()
    meta = {**log_meta(info, args.port, "delta6 log --port"), "rate_hz": rate,
            "frame_id": args.frame_id,
            # UNIX time = host_t + this: dates the MCAP messages (docs/log-format.md)
            "host_clock_offset": f"{time.time() - time.monotonic():.6f}"}
    writer = open_log_writer(args.output, meta, optional=("seq", "status", "host_t"),
                             overwrite=args.force)
    stats = Stats(writer)
    session: list = []
    started = time.monotonic()
    next_show = started
    try:
        while args.duration is None or time.monotonic() - started < args.duration:
            block = next_block(dev, stop)
            if block is None:
                break
            _write(stats, block, session)
            now = time.monotonic()
            if now >= next_show:
                limit = f" / {args.duration:g}" if args.duration else ""
                progress.show(f"{now - started:7.1f}{limit} s  {stats.rows} samples  "
                              f"{stats.rate():7.1f} Hz  lost {dev.health.samples_lost}  "
                              f"flagged {stats.flagged}")
                next_show = now + 0.5
    except (DeviceError, LogError) as exc:
        ending = exc
    except KeyboardInterrupt:       # a second stop signal: end now, keep what is written
        stop.signum = stop.signum or 2
        # It may have landed between taking a block off the queue and writing it: draining
        # what came after would leave a hole in the log, not only a shorter one (the device
        # is stopped when the port closes).
        cut = True
    finally:
        complete = not isinstance(ending, LogError)
        if not cut and (ending is None
                        or not isinstance(ending, (DeviceRestarted, LogError))):
            try:
                if ending is None:
                    # Stop the stream first: the records sent before STOP's answer all
                    # arrive before it (one queue), so the drain writes every one of them.
                    # One attempt (Device.stop does not leave it to close() to try again),
                    # and a second stop signal while it waits ends only the wait.
                    try:
                        dev.stop()
                    except DeviceError:
                        unstopped = "STOP was not acknowledged"
                    except KeyboardInterrupt:
                        stop.signum = stop.signum or 2
                        unstopped = "the wait for STOP's answer was cut short"
                _drain(dev, stats, session)
            except LogError as exc:
                ending, complete = exc, False
            except KeyboardInterrupt:   # a second stop signal while draining: skip the rest
                stop.signum = stop.signum or 2
        # From here the log, then the port, close whole; further signals are only noted.
        stop.hold()
        try:
            path = writer.close(complete=complete)
        except LogError as exc:
            ending, path = exc, writer.partial
        progress.end()
    return path, stats, dev.health, ending, unstopped


def run(args: argparse.Namespace) -> int:
    _check_outputs(args)
    with stop_requests() as stop:
        with open_device(args, capture=args.capture) as dev:
            path, stats, health, ending, unstopped = _record(dev, args, stop)
        # (the port closed under the hold _record set: the stream stopped, the capture whole)
        how = f" (stopped by {stop.name})" if stop.signum else ""
        if unstopped:
            how = f"; {unstopped}: the device may still be streaming{how}"
        print(f"{path}: {stats.summary(health)}{how}", file=sys.stderr)
    if ending is not None:
        if isinstance(ending, LogError):
            raise ending
        raise DeviceError(f"{ending}; {path} keeps the {stats.rows} samples received before")
    return 0
