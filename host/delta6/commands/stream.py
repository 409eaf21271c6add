"""``delta6 stream``: the wrench live, as a readout, rolling plots, CSV or JSON lines on stdout
(for piping), and optionally served to the Foxglove app."""
from __future__ import annotations

import argparse
import dataclasses
import json
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
    frame_id,
    next_block,
    number,
    open_device,
    start_stream,
)
from delta6.commands._signals import stop_requests
from delta6.commands._termplot import RollingPlot
from delta6.core import calibration as calibration_mod
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.core.paths import DEFAULT_DESIGN
from delta6.learning import LearnedEstimator
from delta6.link.logfile import THETA_COLUMNS, WRENCH_COLUMNS
from delta6.link.ros2msg import DEFAULT_FRAME_ID

NAME = "stream"
HELP = ("show the wrench live: readout, plots, CSV or JSON lines; serve it to Foxglove "
        "(Ctrl-C, SIGTERM or SIGHUP end it)")
FORMATS = ("table", "csv", "jsonl")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    add_stream_arguments(parser)
    parser.add_argument("--duration", type=number("--duration", low=0, low_open=True), metavar="S",
                        help="stop after S seconds")
    parser.add_argument("--interval", type=number("--interval", low=0, low_open=True),
                        default=0.1, metavar="S",
                        help="seconds between display updates (default 0.1)")
    parser.add_argument("--model", metavar="MODEL.onnx",
                        help="the wrench of a learned estimator (delta6 train) instead of the "
                             "device's, in every output: streams the raw counts at the model's "
                             "rate")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="with --model: the device's design (default: the paper's)")
    parser.add_argument("--calibration", metavar="CAL.toml",
                        help="with --model: the calibration a residual model was trained over "
                             "(applied on the host to the raw counts)")
    parser.add_argument("--format", choices=FORMATS, default="table",
                        help="table: one readout line updated in place (default); csv, jsonl: "
                             "every sample on stdout, for piping")
    parser.add_argument("--plot", action="store_true",
                        help="rolling plots of the six axes in the terminal (with --format table)")
    parser.add_argument("--plot-seconds", type=number("--plot-seconds", low=0, low_open=True),
                        default=5.0, metavar="S", help="time span of the plots (default 5)")
    parser.add_argument("--foxglove", action="store_true",
                        help="also serve the stream to the Foxglove app over WebSocket "
                             "(same ROS 2 topics as the MCAP log)")
    parser.add_argument("--foxglove-port", type=number("--foxglove-port", int, 0, 65535),
                        default=8765, metavar="N", help="WebSocket port (default 8765; 0: any)")
    parser.add_argument("--foxglove-host", default="127.0.0.1", metavar="HOST",
                        help="address to listen on (default 127.0.0.1; 0.0.0.0 for the network)")
    parser.add_argument("--frame-id", type=frame_id, default=DEFAULT_FRAME_ID, metavar="ID",
                        help=f"frame id of the wrench messages (default {DEFAULT_FRAME_ID})")


def format_line(t: float, wrench: np.ndarray, status: int, rate: float, lost: int) -> str:
    values = " ".join(f"{a} {v:+8.3f}" if np.isfinite(v) else f"{a}      nan"
                      for a, v in zip(AXES[:3], wrench[:3]))
    values += "  " + " ".join(f"{a} {v:+7.4f}" if np.isfinite(v) else f"{a}     nan"
                              for a, v in zip(AXES[3:], wrench[3:]))
    return (f"t {t:9.3f} s  {values}  {rate:6.0f} Hz  lost {lost}  {flag_names(status)}")


def csv_header(raw: bool) -> str:
    return ",".join(("t",) + (THETA_COLUMNS if raw else ()) + WRENCH_COLUMNS
                    + ("seq", "status", "host_t"))


def csv_rows(block, raw: bool) -> str:
    """Every sample of a block as the log format's columns (times with 6 decimals, values with
    9 significant digits, NaN empty)."""
    cols = [block.t[:, None]] + ([block.theta] if raw else []) + [
        block.wrench, block.seq[:, None], block.status[:, None], block.host_t[:, None]]
    table = np.hstack([np.asarray(c, float) for c in cols])
    lines = []
    n_float = table.shape[1] - 3
    for row in table:
        cells = [f"{row[0]:.6f}"]
        cells += ["" if not np.isfinite(v) else f"{v:.9g}" for v in row[1:n_float]]
        cells += [str(int(row[n_float])), str(int(row[n_float + 1])), f"{row[-1]:.6f}"]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def jsonl_rows(block, raw: bool) -> str:
    """Every sample as one JSON object per line (NaN as null)."""
    def values(v):
        return [_short(x) for x in v]
    out = []
    for i in range(len(block.t)):
        record = {"t": round(float(block.t[i]), 6), "seq": int(block.seq[i]),
                  "status": int(block.status[i]), "flags": flag_names(int(block.status[i]), 0),
                  "wrench": values(block.wrench[i])}
        if raw:
            record["theta"] = values(block.theta[i])
        record["host_t"] = float(block.host_t[i])
        out.append(json.dumps(record, separators=(",", ":")))
    return "\n".join(out) + "\n"


def _short(x) -> float | None:
    """The value at 9 significant digits (0.412, not 0.41200000000000003), None for NaN."""
    return float(f"{x:.9g}") if np.isfinite(x) else None


class _Screen:
    """Whole-screen frames: redrawn in place on a terminal, separated by a blank line otherwise."""

    def __init__(self, stream):
        self.stream, self.tty = stream, stream.isatty()

    def show(self, text: str) -> None:
        self.stream.write(("\x1b[H\x1b[J" if self.tty else "") + text + "\n"
                          + ("" if self.tty else "\n"))
        self.stream.flush()

    def end(self) -> None:
        pass


class _Sessions:
    """Notices where a block's samples come from a new device session and says so on stderr,
    as ``delta6 log`` does: the stream goes on, its times start again. A new session is a
    restart when the device confirmed one (a BOOT event, another boot id); counters that only
    stop following on may also be a host that fell behind by 2^15 records or more."""

    def __init__(self):
        self.current = None
        self.restarts = 0           # confirmed by the device
        self.breaks = 0             # counters that began again, unconfirmed
        self._reboots = 0

    def update(self, block, reboots: int) -> int | None:
        """Where in ``block`` its last new session starts (None: no new session); ``reboots``
        is the device's count of confirmed restarts (:attr:`Device.reboots`)."""
        if block.session is None or not len(block):
            return None
        if self.current is None:
            self.current = int(block.session[0])
            self._reboots = reboots         # restarts before the stream began are no break
        starts = np.flatnonzero(np.diff(block.session, prepend=self.current))
        # A confirmation may come before the block with the new session: kept until then.
        confirmed = reboots - self._reboots
        self._reboots += min(confirmed, starts.size)
        for i, at in enumerate(starts):
            if i < confirmed:
                self.restarts += 1
                why = "the device restarted: a new session"
            else:
                self.breaks += 1
                why = ("the session broke (its counters do not follow on: a restart without "
                       "its BOOT event, or 32768 records or more lost): a new session")
            print(f"{why} from its time {block.t[at]:.6f} s", file=sys.stderr)
        self.current = int(block.session[-1])
        return int(starts[-1]) if starts.size else None

    def summary(self) -> str:
        def times(n):
            return f"{n} time" + ("s" if n > 1 else "")
        return ((f", the device restarted {times(self.restarts)}" if self.restarts else "")
                + (f", the session broke {times(self.breaks)}" if self.breaks else ""))


def learned_estimator(args: argparse.Namespace):
    """The streaming estimator of ``--model`` (None without it); the stream is then raw, at
    the model's rate."""
    if args.model is None:
        if args.calibration:
            raise UserError("--calibration goes with --model (a residual over a calibration)")
        return None
    calibration = calibration_mod.load(args.calibration) if args.calibration else None
    estimator = LearnedEstimator(args.model, design=load(args.design),
                                 calibration=calibration).streaming()
    model_rate = estimator.estimator.rate_hz
    if args.rate is not None and abs(args.rate / model_rate - 1) > 0.02:
        raise UserError(f"--rate {args.rate}: {args.model} was trained on samples at "
                        f"{model_rate:g} Hz")
    if abs(model_rate - round(model_rate)) > 1e-6:
        raise UserError(f"{args.model} was trained at {model_rate:g} Hz, which the device "
                        "cannot sample at")
    args.rate, args.raw = int(round(model_rate)), True
    return estimator


def run(args: argparse.Namespace) -> int:
    if args.plot and args.format != "table":
        raise UserError("--plot draws on the terminal; it does not combine with --format "
                        f"{args.format}")
    out = sys.stdout
    display = _Screen(out) if args.plot else Progress(out) if args.format == "table" else None
    plot = RollingPlot(args.plot_seconds) if args.plot else None
    live = None
    learned = learned_estimator(args)
    raw = bool(args.raw)
    flags = 0
    sessions = _Sessions()
    with stop_requests() as stop, open_device(args) as dev:
        if learned is not None:
            learned.check_device(dev.info())
        rate = start_stream(dev, args)
        if learned is not None:
            print(f"learned estimator: {learned.estimator.card.describe()}", file=sys.stderr)
        if args.foxglove:
            from delta6.link.foxglovelive import FoxgloveLive
            info = dev.info()
            live = FoxgloveLive(args.foxglove_host, args.foxglove_port, args.frame_id,
                                f"{info.design_name} 0x{info.serial_number:08x}")
            print(f"Foxglove: open connection ws://{args.foxglove_host}:{live.port}",
                  file=sys.stderr)
        print(f"streaming {rate} Hz from {args.port} (forces N, moments N*m; Ctrl-C ends)",
              file=sys.stderr)
        if args.format == "csv":
            out.write(csv_header(raw) + "\n")
        started = time.monotonic()
        next_show = started
        window = []          # device times of the samples since the last update
        try:
            while args.duration is None or time.monotonic() - started < args.duration:
                block = next_block(dev, stop)
                if block is None:
                    break
                flags += flagged(block.status)
                since = sessions.update(block, dev.reboots)
                if since is not None:   # device times start again: no rate across the restart
                    window = []
                if learned is not None:
                    block = dataclasses.replace(
                        block, wrench=learned.update_block(block.t, block.theta, block.session))
                if live is not None:
                    live.publish(block)
                if args.format == "csv":
                    out.write(csv_rows(block, raw))
                    out.flush()
                    continue
                if args.format == "jsonl":
                    out.write(jsonl_rows(block, raw))
                    out.flush()
                    continue
                window.append(block.t if since is None else block.t[since:])
                if plot is not None:
                    plot.add(block.t, block.wrench)
                now = time.monotonic()
                if now >= next_show:
                    times = np.concatenate(window)
                    span = times[-1] - times[0]
                    measured = (len(times) - 1) / span if span > 0 else 0.0
                    line = format_line(block.t[-1], block.wrench[-1], int(block.status[-1]),
                                       measured, dev.health.samples_lost)
                    display.show(plot.render() + "\n" + line if plot is not None else line)
                    window = [block.t[-1:]]
                    next_show = now + args.interval
        except KeyboardInterrupt:       # a second stop signal
            pass
        finally:
            if display is not None:
                display.end()
            if live is not None:
                live.close()
        health = dev.health
    how = f" (stopped by {stop.name})" if stop.signum else ""
    print(f"{health.summary()}, {flags} flagged" + sessions.summary()
          + (f"; {live.published} samples served to Foxglove" if live else "") + how,
          file=sys.stderr)
    return 0
