"""``delta6 flash``: generate the headers for a design, build and upload the firmware with
PlatformIO, then check that the board answers with the design it was built for."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from delta6.build import flash
from delta6.commands._port import number
from delta6.commands.codegen import HEADER_RELPATH, _write_if_changed, header_text, source_label
from delta6.core import paths
from delta6.core.errors import UserError
from delta6.link.device import DEFAULT_BAUD

NAME = "flash"
HELP = ("generate the headers, build and upload the firmware with PlatformIO (nano_every), and "
        "check the board answers with the expected design hash")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True, metavar="P",
                        help="the board's serial port (/dev/ttyACM0, COM3)")
    parser.add_argument("--design", metavar="DESIGN.toml", type=Path,
                        default=paths.DEFAULT_DESIGN,
                        help="design to build the firmware for (default: designs/delta6.toml)")
    parser.add_argument("--calibration", metavar="CAL.toml", type=Path,
                        help="per-unit calibration to build in (needs firmware that carries one)")
    parser.add_argument("--model", metavar="MODEL", type=Path,
                        help="learned estimator to build in (needs firmware that carries one)")
    parser.add_argument("--env", default=flash.DEFAULT_ENV, metavar="ENV",
                        help=f"PlatformIO environment (default {flash.DEFAULT_ENV}; see "
                             "firmware/platformio.ini)")
    parser.add_argument("--pio", metavar="PATH", help="the PlatformIO executable (default: pio "
                                                      "beside this Python, then on PATH)")
    parser.add_argument("--firmware-dir", metavar="DIR", type=Path,
                        help="the PlatformIO project (default: the checkout's firmware/)")
    parser.add_argument("--baud", type=number("--baud", int, 1), default=DEFAULT_BAUD,
                        help=f"baud rate of the firmware (default {DEFAULT_BAUD})")
    parser.add_argument("--timeout", type=number("--timeout", low=0, low_open=True),
                        default=flash.ANSWER_TIMEOUT, metavar="S",
                        help=f"seconds to wait for the board to answer after the upload "
                             f"(default {flash.ANSWER_TIMEOUT:g})")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the header and the PlatformIO command, change and run nothing")


def run(args: argparse.Namespace) -> int:
    for option, value in (("--calibration", args.calibration), ("--model", args.model)):
        if value is not None:
            raise UserError(f"{option}: this firmware version builds in no {option[2:]} (its info "
                            "record carries the design hash only); flash without it")
    firmware_dir = args.firmware_dir or paths.checkout() / "firmware"
    if not (firmware_dir / "platformio.ini").is_file():
        raise UserError(f"{firmware_dir}: no platformio.ini (not the firmware project)")
    design, text = header_text(args.design)
    expected = flash.Expected(design.name, design.hash32())
    header = firmware_dir / "include" / HEADER_RELPATH
    pio = args.pio or "pio"
    if not args.dry_run:
        pio = flash.find_pio(args.pio)
    command = flash.pio_command(pio, firmware_dir, args.env, args.port)
    if args.dry_run:
        print(f"would write {header} for {expected.describe()} from {source_label(args.design)}")
        print("would run: " + " ".join(command))
        print(f"then expect the board on {args.port} to report {expected.describe()}")
        return 0
    verb = "wrote" if _write_if_changed(header, text) else "unchanged:"
    print(f"{verb} {header} for {expected.describe()}", file=sys.stderr)
    print("running: " + " ".join(command), file=sys.stderr)
    flash.run_pio(command)
    info = flash.check_board(args.port, expected, baud=args.baud, timeout=args.timeout)
    print(f"flashed: the board on {args.port} reports {expected.describe()}, firmware "
          f"{info.firmware_version}, protocol {info.protocol_version}")
    return 0
