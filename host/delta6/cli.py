"""The ``delta6`` command line. Each subcommand lives in its own module under
``delta6.commands`` and provides ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``."""
from __future__ import annotations

import argparse
import importlib
import sys

from delta6 import __version__
from delta6.core.design import DesignError
from delta6.core.errors import UserError

#: Subcommand modules, in the order ``delta6 --help`` lists them.
COMMAND_MODULES = ("design", "codegen", "virtual", "info", "stream", "log", "tare", "decode",
                   "convert", "simulate", "diagnose", "calibrate", "evaluate", "flash", "train")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="delta6", description=__doc__.split("\n")[0])
    parser.add_argument("--version", action="version", version=f"delta6 {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        module = importlib.import_module(f".commands.{name}", __package__)
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except (DesignError, UserError) as exc:
        print(f"delta6 {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"delta6 {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # Output piped into e.g. `head`: not an error of ours.
        return 0


if __name__ == "__main__":
    sys.exit(main())
