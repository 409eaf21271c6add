"""The ``delta6`` console script: :func:`delta6.cli.main` with Ctrl-C handled from the first
instant to the last. The command line takes a quarter of a second to import (numpy, the
commands); a Ctrl-C then, or after the command's own handling has ended, would print a
KeyboardInterrupt traceback or end the program silently with 130. Here it ends it as any
interrupted command ends: one line, status 130 (128 + the signal's number)."""
import os
import signal
import sys


def _interrupted(signum: int = signal.SIGINT, _frame=None) -> None:
    name = signal.Signals(signum).name
    print(f"delta6: interrupted ({name})", file=sys.stderr, flush=True)
    sys.stdout.flush()
    os._exit(128 + signum)


def main() -> int:
    try:
        from delta6.cli import main as cli_main  # the heavy import
        status = cli_main()
    except KeyboardInterrupt as exc:        # SIGTERM and SIGHUP raise one too, with a signum
        _interrupted(getattr(exc, "signum", signal.SIGINT))
    # The command is done; a Ctrl-C from here to the exit says so too, instead of nothing.
    signal.signal(signal.SIGINT, _interrupted)
    return status


if __name__ == "__main__":
    sys.exit(main())
