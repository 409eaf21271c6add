"""``delta6 config``: the device's wrench pipeline (low-pass filter, tool frame, overload
limits), set by command and optionally saved to its EEPROM."""
from __future__ import annotations

import argparse
import math

import numpy as np

from delta6.commands._port import AXES, add_port_arguments, open_device
from delta6.link.device import DeviceError, limit_counts
from delta6.link.protocol import Info

NAME = "config"
HELP = ("set the device's low-pass filter, tool frame and overload limits "
        "(--save keeps them over power-off)")


def _numbers(option: str, count: int, *, allow_none: bool = False):
    """An argparse type: ``count`` comma-separated numbers (``-`` for none where allowed);
    ``off`` gives an empty list (the identity tool frame, no limits)."""
    def convert(text: str):
        if text.strip().lower() in ("off", "none"):
            return []
        parts = [p.strip() for p in text.split(",")]
        if len(parts) != count:
            raise argparse.ArgumentTypeError(f"{option} takes {count} comma-separated numbers, "
                                             f"got {len(parts)} in {text!r}")
        out = []
        for p in parts:
            if allow_none and p in ("-", ""):
                out.append(None)
                continue
            try:
                value = float(p)
            except ValueError:
                raise argparse.ArgumentTypeError(f"{option}: {p!r} is not a number") from None
            if not math.isfinite(value):
                raise argparse.ArgumentTypeError(f"{option}: {p!r} is not a finite number")
            out.append(value)
        return out
    return convert


def _cutoff(text: str):
    if text.strip().lower() in ("off", "0"):
        return 0.0
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--filter-hz takes a cutoff in Hz or 'off', got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"--filter-hz must be positive (or 'off'), got {text}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    parser.add_argument("--filter-hz", type=_cutoff, metavar="HZ",
                        help="low-pass cutoff in Hz (0.001 .. 0.45 x the sample rate), "
                             "or 'off'")
    parser.add_argument("--tool", type=_numbers("--tool", 6), metavar="X,Y,Z,ROLL,PITCH,YAW",
                        help="report the wrench at the tool point X,Y,Z (m, in the sensor "
                             "frame {E}) in axes rotated by ROLL,PITCH,YAW (degrees, about "
                             "x, y, z of {E}); 'off' for the sensor frame")
    parser.add_argument("--limits", type=_numbers("--limits", 6, allow_none=True),
                        metavar="FX,FY,FZ,MX,MY,MZ",
                        help="overload thresholds (N, N*m; '-' or 0 for none on an axis, 'off' "
                             "for none): a sample over one is flagged OVERRANGE")
    parser.add_argument("--save", action="store_true",
                        help="store the configuration in the device's EEPROM")


def run(args: argparse.Namespace) -> int:
    with open_device(args) as dev, dev.restart_guard("config"):
        tool = limits = None
        if args.filter_hz is not None:
            dev.set_filter(args.filter_hz)
        if args.tool is not None:
            tool = args.tool or [0.0] * 6
            tool = [*tool[:3], *(math.radians(a) for a in tool[3:])]
            dev.set_tool(tool[:3], tool[3:])
        if args.limits is not None:
            limits = args.limits or [None] * 6
            dev.set_limits(limits)
        if args.save:
            # Save only what was set: a device that lost it (a restart the guard did not see,
            # a firmware that ignored a command) would store something else.
            _check_read_back(dev.info(refresh=True), args.filter_hz, tool, limits, dev.port)
            dev.save_config()
        info = dev.info(refresh=True)
    print("\n".join(pipeline_lines(info)))
    if args.save:
        print("configuration saved to EEPROM")
    return 0


def _check_read_back(info: Info, cutoff, tool, limits, port: str) -> None:
    """Raise unless the device reports the cutoff, tool frame and limits just set (each as
    the float32 or counts the device holds)."""
    wrong = []
    if cutoff is not None and np.float32(info.filter_hz) != np.float32(cutoff):
        wrong.append(f"a filter of {info.filter_hz:g} Hz instead of {cutoff:g} Hz")
    if tool is not None and not np.array_equal(
            np.float32([*info.tool_translation, *info.tool_rpy]), np.float32(tool)):
        wrong.append("another tool frame")
    if limits is not None and list(info.limits) != limit_counts(limits, info.lsb):
        wrong.append("other overload limits")
    if wrong:
        raise DeviceError(f"{port} does not report what was just set ({', '.join(wrong)}): "
                          "nothing saved")


def pipeline_lines(info: Info) -> list[str]:
    """The filter, tool frame and limits of an info record, for ``delta6 info`` and ``config``."""
    lines = [f"  filter: {'off' if not info.filter_hz else f'low-pass {info.filter_hz:g} Hz (Butterworth, 2nd order)'}"]
    translation, rpy = info.tool_translation, info.tool_rpy
    if not any(translation) and not any(rpy):
        lines.append("  tool frame: none (the sensor frame {E})")
    else:
        lines.append("  tool frame: point " + ", ".join(f"{v:g}" for v in translation)
                     + " m; roll, pitch, yaw " + ", ".join(f"{math.degrees(v):g}" for v in rpy)
                     + " deg")
    values = info.limit_values
    if all(c == 0 for c in info.limits):
        lines.append("  overload limits: none")
    else:
        unit = ("N",) * 3 + ("N*m",) * 3
        lines.append("  overload limits: " + ", ".join(
            f"{axis} {'-' if math.isnan(v) else f'{v:g} {u}'}"
            for axis, v, u in zip(AXES, values, unit)))
    return lines
