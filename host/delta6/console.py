"""The ``delta6`` console script: :func:`delta6.cli.main` with Ctrl-C handled from the first
instant to the last. The command line takes a quarter of a second to import (numpy, the
commands); a Ctrl-C then, or after the command's own handling has ended, would print a
KeyboardInterrupt traceback or end the program silently with 130. Here it ends it as any
interrupted command ends: one line, status 130 (128 + the signal's number).

The program ends in :func:`main`, not in the interpreter's shutdown: there Python gives SIGINT
back to the system's default, and a Ctrl-C while modules are torn down ended the program
silently with 130."""
import atexit
import os
import signal
import sys


def _interrupted(signum: int = signal.SIGINT, _frame=None) -> None:
    name = signal.Signals(signum).name
    print(f"delta6: interrupted ({name})", file=sys.stderr, flush=True)
    sys.stdout.flush()
    os._exit(128 + signum)


def main():
    """Run the command line and end the process with its status (never returns)."""
    try:
        from delta6.cli import main as cli_main  # the heavy import
        status = cli_main()
    except SystemExit as exc:                # argparse: --help, a usage error
        if not isinstance(exc.code, (int, type(None))):
            raise
        status = exc.code or 0
    except KeyboardInterrupt as exc:        # SIGTERM and SIGHUP raise one too, with a signum
        _interrupted(getattr(exc, "signum", signal.SIGINT))
    # The command is done; a Ctrl-C from here to the exit says so too, instead of nothing.
    signal.signal(signal.SIGINT, _interrupted)
    atexit._run_exitfuncs()                 # what the shutdown would run (temporary files)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):       # a closed pipe (`| head`): nothing to keep
            pass
    os._exit(status)


if __name__ == "__main__":
    sys.exit(main())
