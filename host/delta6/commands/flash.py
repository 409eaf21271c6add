"""``delta6 flash``: generate the headers for a design (and a unit's calibration and an on-chip
residual model), build and upload the firmware with PlatformIO, then check that the board
answers with the design, calibration and model it was built with."""
from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from delta6.build import flash
from delta6.commands._port import number
from delta6.commands.codegen import (
    ALLOW_IMPLAUSIBLE,
    CALIBRATION_HEADER,
    COMMITTED_HEADER,
    HEADER_RELPATH,
    MODEL_HEADER,
    add_allow_implausible,
    codegen_command,
    generate_headers,
    source_label,
    write_headers,
)
from delta6.core import paths
from delta6.core.errors import UserError
from delta6.link.device import DEFAULT_BAUD

NAME = "flash"
HELP = ("generate the headers, build and upload the firmware with PlatformIO (nano_every), and "
        "check the board answers with the expected design, calibration and model hashes")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", required=True, metavar="P",
                        help="the board's serial port (/dev/ttyACM0, COM3)")
    parser.add_argument("--design", metavar="DESIGN.toml", type=Path,
                        default=paths.DEFAULT_DESIGN,
                        help="design to build the firmware for (default: designs/delta6.toml)")
    parser.add_argument("--calibration", metavar="CAL.toml", type=Path,
                        help="a unit's calibration (delta6 calibrate) to build in, as delta6 "
                             f"codegen --calibration does ({CALIBRATION_HEADER}); without it "
                             "the firmware is the uncalibrated one")
    parser.add_argument("--model", metavar="MODEL.json", type=Path,
                        help="an on-chip residual model (delta6 train --target mcu) to build in, "
                             f"as delta6 codegen --model does ({MODEL_HEADER}); without it none")
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
    add_allow_implausible(parser)


def rerun_command(args: argparse.Namespace) -> str:
    """This ``delta6 flash`` command line, for the banners of the headers it writes."""
    words = ["delta6", NAME, "--port", args.port, "--design", source_label(args.design)]
    for flag, value in (("--calibration", args.calibration), ("--model", args.model),
                        ("--firmware-dir", args.firmware_dir)):
        if value is not None:
            words += [flag, source_label(value)]
    if args.env != flash.DEFAULT_ENV:
        words += ["--env", args.env]
    if args.allow_implausible:
        words.append(ALLOW_IMPLAUSIBLE)
    return shlex.join(words)


def run(args: argparse.Namespace) -> int:
    firmware_dir = args.firmware_dir or paths.checkout() / "firmware"
    if not (firmware_dir / "platformio.ini").is_file():
        raise UserError(f"{firmware_dir}: no platformio.ini (not the firmware project)")
    header = firmware_dir / "include" / HEADER_RELPATH
    # The design header's bytes are what `delta6 codegen DESIGN` writes there (flashing a
    # shipped design, calibrated or not, leaves the committed header as it is).
    extra = ([] if header.resolve() == COMMITTED_HEADER.resolve()
             else ["-o", source_label(header)])
    extra += [ALLOW_IMPLAUSIBLE] if args.allow_implausible else []
    headers = generate_headers(args.design, args.calibration, args.model, args.allow_implausible,
                               rerun_command(args),
                               codegen_command(args.design, None, None, *extra))
    cal, model = headers.cal, headers.model
    expected = flash.Expected(
        headers.design.name, headers.design.hash32(),
        cal.name if cal else "", cal.hash32() if cal else 0,
        model.name if model else "", model.hash32() if model else 0)
    pio = args.pio or "pio"
    if not args.dry_run:
        pio = flash.find_pio(args.pio)
    command = flash.pio_command(pio, firmware_dir, args.env, args.port)
    if args.dry_run:
        print(f"would write {header} for design '{headers.design.name}' (hash "
              f"0x{headers.design.hash32():08x}) from {source_label(args.design)}")
        for name, part in ((CALIBRATION_HEADER, cal), (MODEL_HEADER, model)):
            path = header.with_name(name)
            if part is not None:
                print(f"would write {path} for '{part.name}' (hash 0x{part.hash32():08x})")
            elif path.exists():
                print(f"would remove {path}")
        print("would run: " + " ".join(command))
        print(f"then expect the board on {args.port} to report {expected.describe()}")
        return 0
    for line in write_headers(header, headers):
        print(line, file=sys.stderr)
    print("running: " + " ".join(command), file=sys.stderr)
    flash.run_pio(command)
    info = flash.check_board(args.port, expected, baud=args.baud, timeout=args.timeout)
    print(f"flashed: the board on {args.port} reports {expected.describe()}, firmware "
          f"{info.firmware_version}, protocol {info.protocol_version}")
    return 0
