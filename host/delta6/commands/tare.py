"""``delta6 tare``: zero the wrench on the device (averaged there), optionally persistently."""
from __future__ import annotations

import argparse

from delta6.commands._port import AXES, add_port_arguments, number, open_device
from delta6.core.errors import UserError

NAME = "tare"
HELP = ("tare the wrench on the device (average N samples); --clear undoes it, --save keeps it, "
        "--abort stops one that is averaging")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_port_arguments(parser)
    parser.add_argument("--samples", type=number("--samples", int, 1, 65535), default=100, metavar="N",
                        help="samples to average (default 100)")
    action = parser.add_mutually_exclusive_group()
    action.add_argument("--clear", action="store_true", help="remove the tare instead")
    action.add_argument("--abort", action="store_true",
                        help="stop a tare or zero capture that is averaging (one left running "
                             "by an interrupted program keeps the device busy for minutes)")
    parser.add_argument("--save", action="store_true",
                        help="store the result in the device's EEPROM (survives power-off)")


def run(args: argparse.Namespace) -> int:
    if args.abort and args.save:     # --abort changes nothing: there is nothing to save
        raise UserError("--abort changes nothing to save: give --save without it")
    with open_device(args) as dev:
        if args.abort:
            print("stopped the averaging; nothing was changed" if dev.abort()
                  else "nothing was averaging")
            return 0
        # A restart between the tare and SAVE_CONFIG would save the fresh device's defaults.
        with dev.restart_guard("tare"):
            if args.clear:
                dev.clear_tare()
                print("tare cleared")
            else:
                offsets = dev.tare(args.samples)
                print(f"tare over {args.samples} samples: " + ", ".join(
                    f"{axis} {value:+.5g}" for axis, value in zip(AXES, offsets)) + " (N, N*m)")
            if args.save:
                dev.save_config()
                print("configuration saved to EEPROM")
    return 0
