"""The ``delta6`` command line. Each subcommand lives in its own module under
``delta6.commands`` and provides ``NAME``, ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``."""
from __future__ import annotations

import argparse
import importlib
import re
import sys

from delta6 import __version__
from delta6.commands._signals import exit_status, signal_name, terminate_like_interrupt
from delta6.core.design import DesignError
from delta6.core.errors import UserError

#: Subcommand modules, in the order ``delta6 --help`` lists them.
COMMAND_MODULES = ("design", "codegen", "virtual", "info", "config", "stream", "log", "tare",
                   "decode", "convert", "simulate", "diagnose", "calibrate", "evaluate", "flash",
                   "train")

DESCRIPTION = ("Delta6, a low-cost 6-axis force/torque sensor: design reports, firmware, the "
               "virtual board, the device tools, the digital twin and the gap diagnosis.")
EPILOG = ("Exit status: 0 done; 2 bad input, an unusable file or port, or a lost device (one "
          "line on stderr says which); 1 a check found a difference (codegen --check); 128+N "
          "ended by signal N (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), except for log, stream "
          "and virtual, whose stop is a signal: they end as asked, with status 0. "
          "'delta6 COMMAND --help' "
          "describes each command; docs/reliability.md the promises.")


class _Parser(argparse.ArgumentParser):
    """A usage error is one line, as every other error is (the usage is one --help away)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="delta6", description=DESCRIPTION, epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"delta6 {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMAND_MODULES:
        module = importlib.import_module(f".commands.{name}", __package__)
        # argparse %-formats help strings ("% FS" broke `delta6 --help`); descriptions not.
        cmd = sub.add_parser(module.NAME, help=module.HELP.replace("%", "%%"),
                             description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


#: A comma-separated list that starts with a minus sign: a negative number ("-0.01,0,0.05") or
#: the "-" that stands for none ("-,-,20,-,-,-").
_NEGATIVE_LIST = re.compile(r"-(\.?\d[^,\s]*)?(,[^,\s]*)+")


def joined_negative_lists(argv: list[str]) -> list[str]:
    """``--tool -0.01,0,...`` as ``--tool=-0.01,0,...``: argparse takes a value that starts with
    a minus sign for an option unless it is a single number, so a tool point with a negative
    first coordinate, or limits starting with '-' (none), were refused as a missing argument."""
    out: list[str] = []
    for token in argv:
        previous = out[-1] if out else ""
        if (_NEGATIVE_LIST.fullmatch(token) and previous.startswith("--")
                and "=" not in previous and previous != "--"):
            out[-1] = f"{previous}={token}"
        else:
            out.append(token)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(joined_negative_lists(sys.argv[1:] if argv is None else argv))
    try:
        with terminate_like_interrupt():
            return int(args._run(args) or 0)
    except (DesignError, UserError) as exc:
        print(f"delta6 {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"delta6 {args.command}: interrupted ({signal_name(exc)})", file=sys.stderr)
        return exit_status(exc)
    except BrokenPipeError:
        # Output piped into e.g. `head`: not an error of ours.
        return 0
    except OSError as exc:
        # A file system failure no command foresaw (a full disk, a vanished folder): one line.
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"delta6 {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
