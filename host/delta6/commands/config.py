"""``delta6 config``: the device's wrench pipeline (low-pass filter, tool frame, overload
limits), set by command and optionally saved to its EEPROM."""
from __future__ import annotations

import argparse
import math

from delta6.commands._port import AXES, add_port_arguments, open_device
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
    with open_device(args) as dev:
        if args.filter_hz is not None:
            dev.set_filter(args.filter_hz)
        if args.tool is not None:
            tool = args.tool or [0.0] * 6
            dev.set_tool(tool[:3], [math.radians(a) for a in tool[3:]])
        if args.limits is not None:
            dev.set_limits(args.limits or [None] * 6)
        if args.save:
            dev.save_config()
        info = dev.info(refresh=True)
    print("\n".join(pipeline_lines(info)))
    if args.save:
        print("configuration saved to EEPROM")
    return 0


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
