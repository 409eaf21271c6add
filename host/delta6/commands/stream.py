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
    number,
    open_device,
    start_stream,
)

from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.core.paths import DEFAULT_DESIGN
from delta6.learning import LearnedEstimator

NAME = "stream"
HELP = "show the wrench live (Ctrl-C ends it)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    add_stream_arguments(parser)
    parser.add_argument("--duration", type=number("--duration", low=0, low_open=True), metavar="S",
                        help="stop after S seconds")
    parser.add_argument("--model", metavar="MODEL.onnx",
                        help="show the wrench of a learned estimator (delta6 train) instead of "
                             "the device's: streams the raw counts at the model's rate")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="with --model: the device's design (default: the paper's)")
    parser.add_argument("--interval", type=number("--interval", low=0, low_open=True),
                        default=0.1, metavar="S",
                        help="seconds between display updates (default 0.1)")


def format_line(t: float, wrench: np.ndarray, status: int, rate: float, lost: int) -> str:
    values = " ".join(f"{a} {v:+8.3f}" if np.isfinite(v) else f"{a}      nan"
                      for a, v in zip(AXES[:3], wrench[:3]))
    values += "  " + " ".join(f"{a} {v:+7.4f}" if np.isfinite(v) else f"{a}     nan"
                              for a, v in zip(AXES[3:], wrench[3:]))
    return (f"t {t:9.3f} s  {values}  {rate:6.0f} Hz  lost {lost}  {flag_names(status)}")


def learned(args: argparse.Namespace):
    """The streaming estimator of ``--model`` (None without it); the stream is then raw, at
    the model's rate."""
    if args.model is None:
        return None
    live = LearnedEstimator(args.model, design=load(args.design)).streaming()
    model_rate = live.estimator.rate_hz
    if args.rate is not None and abs(args.rate / model_rate - 1) > 0.02:
        raise UserError(f"--rate {args.rate}: {args.model} was trained on samples at "
                        f"{model_rate:g} Hz")
    if abs(model_rate - round(model_rate)) > 1e-6:
        raise UserError(f"{args.model} was trained at {model_rate:g} Hz, which the device "
                        "cannot sample at")
    args.rate, args.raw = int(round(model_rate)), True
    return live


def run(args: argparse.Namespace) -> int:
    display = Progress(sys.stdout)
    live = learned(args)
    with open_device(args) as dev:
        if live is not None:
            live.check_device(dev.info())
        rate = start_stream(dev, args)
        if live is not None:
            print(f"learned estimator: {live.estimator.card.describe()}", file=sys.stderr)
        print(f"streaming {rate} Hz from {args.port} (forces N, moments N*m; Ctrl-C ends)",
              file=sys.stderr)
        started = time.monotonic()
        next_show = started
        window = []          # device times of the samples since the last update
        try:
            while args.duration is None or time.monotonic() - started < args.duration:
                block = dev.read_block()
                wrench = block.wrench if live is None else live.update_block(block.t, block.theta)
                window.append(block.t)
                now = time.monotonic()
                if now >= next_show:
                    times = np.concatenate(window)
                    span = times[-1] - times[0]
                    measured = (len(times) - 1) / span if span > 0 else 0.0
                    display.show(format_line(block.t[-1], wrench[-1],
                                             int(block.status[-1]), measured,
                                             dev.health.samples_lost))
                    window = [block.t[-1:]]
                    next_show = now + args.interval
        except KeyboardInterrupt:
            pass
        finally:
            display.end()
        print(dev.health.summary(), file=sys.stderr)
    return 0
