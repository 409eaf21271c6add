"""``delta6 stream``: a live readout of the wrench."""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from delta6.commands._port import (
    AXES,
    Progress,
    add_port_arguments,
    add_stream_arguments,
    flag_names,
    flagged,
    next_block,
    number,
    open_device,
    start_stream,
)
from delta6.commands._signals import stop_requests

NAME = "stream"
HELP = "show the wrench live (Ctrl-C, SIGTERM or SIGHUP end it)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    add_stream_arguments(parser)
    parser.add_argument("--duration", type=number("--duration", low=0, low_open=True), metavar="S",
                        help="stop after S seconds")
    parser.add_argument("--interval", type=number("--interval", low=0, low_open=True),
                        default=0.1, metavar="S",
                        help="seconds between display updates (default 0.1)")


def format_line(t: float, wrench: np.ndarray, status: int, rate: float, lost: int) -> str:
    values = " ".join(f"{a} {v:+8.3f}" if np.isfinite(v) else f"{a}      nan"
                      for a, v in zip(AXES[:3], wrench[:3]))
    values += "  " + " ".join(f"{a} {v:+7.4f}" if np.isfinite(v) else f"{a}     nan"
                              for a, v in zip(AXES[3:], wrench[3:]))
    return (f"t {t:9.3f} s  {values}  {rate:6.0f} Hz  lost {lost}  {flag_names(status)}")


def run(args: argparse.Namespace) -> int:
    display = Progress(sys.stdout)
    flags = 0
    with stop_requests() as stop, open_device(args) as dev:
        rate = start_stream(dev, args)
        print(f"streaming {rate} Hz from {args.port} (forces N, moments N*m; Ctrl-C ends)",
              file=sys.stderr)
        started = time.monotonic()
        next_show = started
        window = []          # device times of the samples since the last update
        try:
            while args.duration is None or time.monotonic() - started < args.duration:
                block = next_block(dev, stop)
                if block is None:
                    break
                window.append(block.t)
                flags += flagged(block.status)
                now = time.monotonic()
                if now >= next_show:
                    times = np.concatenate(window)
                    span = times[-1] - times[0]
                    measured = (len(times) - 1) / span if span > 0 else 0.0
                    display.show(format_line(block.t[-1], block.wrench[-1],
                                             int(block.status[-1]), measured,
                                             dev.health.samples_lost))
                    window = [block.t[-1:]]
                    next_show = now + args.interval
        except KeyboardInterrupt:       # a second stop signal
            pass
        finally:
            display.end()
        health = dev.health
    how = f" (stopped by {stop.name})" if stop.signum else ""
    print(f"{health.summary()}, {flags} flagged{how}", file=sys.stderr)
    return 0
