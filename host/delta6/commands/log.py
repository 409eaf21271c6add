"""``delta6 log``: record the stream to a log file (docs/log-format.md), safely: CSV, or MCAP
with ROS 2 messages when the file name ends in ``.mcap``.

Rows go to FILE.partial and are flushed as they come; the file is renamed to FILE when the log
closes: at the end of --duration, on Ctrl-C, and also when the port disappears or the device
restarts (the message says so and the exit status is non-zero). Nothing received is lost.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from delta6.commands._port import (
    Progress,
    add_port_arguments,
    add_stream_arguments,
    log_meta,
    number,
    open_device,
    start_stream,
)
from delta6.link.device import DeviceError
from delta6.link.logfile import LogWriter, open_log_writer
from delta6.link.ros2msg import DEFAULT_FRAME_ID

NAME = "log"
HELP = "record the wrench stream to a log, CSV or MCAP (progress shown; Ctrl-C ends it cleanly)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="FILE",
                        help="log file: CSV, or MCAP with ROS 2 messages when it ends in .mcap")
    parser.add_argument("--frame-id", default=DEFAULT_FRAME_ID, metavar="ID",
                        help=f"frame id of the wrench messages (default {DEFAULT_FRAME_ID})")
    parser.add_argument("--duration", type=number("--duration", low=0, low_open=True), metavar="S",
                        help="seconds to record (default: until Ctrl-C)")
    add_stream_arguments(parser)
    parser.add_argument("--capture", metavar="FILE.bin",
                        help="also keep every received byte (delta6 decode reads it)")


class Stats:
    """Rate and loss figures of a log being written (its rows: ``writer.rows``)."""

    def __init__(self, writer: LogWriter):
        self.writer = writer
        self.first_t = self.last_t = None
        self.first_seq = self.last_seq = None

    @property
    def rows(self) -> int:
        return self.writer.rows

    def add(self, block) -> None:
        if self.first_t is None:
            self.first_t, self.first_seq = block.t[0], int(block.seq[0])
        self.last_t, self.last_seq = block.t[-1], int(block.seq[-1])

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
                + health.link_summary())


class DeviceRestarted(DeviceError):
    """The device rebooted mid-log: its clock and sequence start again."""


def _write(stats: Stats, block) -> None:
    """Append a block; a device that restarted (time not increasing) ends the log there, as a
    log's time must increase and the samples after a reboot belong to a new one."""
    t = np.concatenate(([stats.last_t], block.t)) if stats.rows else block.t
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        keep = int(back[0]) + (0 if stats.rows else 1)
        if keep:
            _write(stats, block.head(keep))
        raise DeviceRestarted("the device restarted during the log (its clock went back)")
    stats.writer.write_block(block.t, block.theta, block.wrench, seq=block.seq,
                             status=block.status, host_t=block.host_t)
    stats.add(block)


def _drain(dev, stats: Stats) -> None:
    """Write what was received but not yet read: the log keeps every sample that arrived."""
    while True:
        try:
            _write(stats, dev.read_block(timeout=0.0))
        except DeviceError:
            return


def run(args: argparse.Namespace) -> int:
    progress = Progress()
    with open_device(args, capture=args.capture) as dev:
        rate = start_stream(dev, args)
        info = dev.info()
        meta = {**log_meta(info, args.port, "delta6 log --port"), "rate_hz": rate,
                "frame_id": args.frame_id,
                # UNIX time = host_t + this: dates the MCAP messages (docs/log-format.md)
                "host_clock_offset": f"{time.time() - time.monotonic():.6f}"}
        writer = open_log_writer(args.output, meta, optional=("seq", "status", "host_t"))
        stats = Stats(writer)
        started = time.monotonic()
        next_show = started
        lost: DeviceError | None = None
        interrupted = False
        try:
            while args.duration is None or time.monotonic() - started < args.duration:
                try:
                    _write(stats, dev.read_block())
                except DeviceError as exc:
                    lost = exc
                    break
                now = time.monotonic()
                if now >= next_show:
                    limit = f" / {args.duration:g}" if args.duration else ""
                    progress.show(f"{now - started:7.1f}{limit} s  {stats.rows} samples  "
                                  f"{stats.rate():7.1f} Hz  lost {dev.health.samples_lost}")
                    next_show = now + 0.5
        except KeyboardInterrupt:
            interrupted = True
        finally:
            if lost is None:
                _drain(dev, stats)
            path = writer.close()
            progress.end()
        health = dev.health
    print(f"{path}: {stats.summary(health)}" + (" (interrupted)" if interrupted else ""),
          file=sys.stderr)
    if lost is not None:
        raise DeviceError(f"{lost}; {path} keeps the {stats.rows} samples received before")
    return 0
