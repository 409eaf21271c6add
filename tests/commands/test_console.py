"""The console script: a Ctrl-C at any moment, from the first import to the exit, ends the
program with one line and status 130, never a traceback and never silently."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from conftest import ROOT


def _python(script: str) -> subprocess.CompletedProcess:
    """``script`` run by a fresh interpreter that imports this checkout's package."""
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT / "host")}, timeout=60)


@pytest.mark.parametrize("module", ["numpy", "delta6.core.design"])
def test_ctrl_c_while_the_command_line_loads_is_one_line(module):
    """The signal lands while ``module`` is being imported (the first quarter second of every
    command; a delay cannot aim there reliably, an import hook can)."""
    script = ("import builtins, os, signal, sys\n"
              "real = builtins.__import__\n"
              "def hook(name, *args, **kwargs):\n"
              f"    if name == {module!r}:\n"
              "        builtins.__import__ = real\n"
              "        os.kill(os.getpid(), signal.SIGINT)\n"
              "    return real(name, *args, **kwargs)\n"
              "builtins.__import__ = hook\n"
              "from delta6 import console\n"
              "sys.argv = ['delta6', 'info', '--port', 'delta6sim://']\n"
              "sys.exit(console.main())\n")
    done = _python(script)
    assert done.returncode == 130, done.stderr
    assert done.stderr == "delta6: interrupted (SIGINT)\n"


def test_ctrl_c_after_the_command_finished_still_says_so():
    """A signal while what the exit runs (atexit) runs: one line and 130."""
    script = ("import atexit, os, signal, sys, time, delta6.cli\n"
              "from delta6 import console\n"
              "atexit.register(lambda: os.kill(os.getpid(), signal.SIGINT) or time.sleep(5))\n"
              "delta6.cli.main = lambda: print('summary') or 0\n"
              "sys.exit(console.main())\n")
    done = _python(script)
    assert done.returncode == 130
    assert done.stdout == "summary\n"
    assert done.stderr == "delta6: interrupted (SIGINT)\n"


def test_the_program_ends_with_the_command_not_in_the_interpreter_shutdown():
    """Where modules are torn down, Python has given SIGINT back to the system's default: a
    Ctrl-C there ended the program silently with 130 (the object below is torn down there and
    sends one). The console ends the process when the command has returned, status and
    output intact, so no such moment comes."""
    script = ("import os, signal, sys, time, delta6.cli\n"
              "from delta6 import console\n"
              "class Late:\n"
              "    def __del__(self):\n"
              "        print('torn down', file=sys.stderr, flush=True)\n"
              "        os.kill(os.getpid(), signal.SIGINT)\n"
              "        time.sleep(5)\n"
              "late = Late()\n"
              "delta6.cli.main = lambda: print('summary') or 3\n"
              "sys.exit(console.main())\n")
    done = _python(script)
    assert (done.returncode, done.stdout, done.stderr) == (3, "summary\n", "")


def test_importing_the_package_loads_no_serial_port_library():
    """``import delta6`` runs before the console handles Ctrl-C: it must stay light."""
    done = _python("import sys, delta6.console\n"
                   "print(sorted(m for m in sys.modules if m.split('.')[0] in "
                   "('serial', 'numpy')))")
    assert done.stdout == "[]\n", done.stderr


def test_usage_errors_and_help_keep_their_status():
    """argparse's own exits (2 for a usage error, 0 for --help) pass through the console."""
    for argv, status in ((["delta6", "--no-such-option"], 2), (["delta6", "--help"], 0)):
        done = _python(f"import sys\nfrom delta6 import console\nsys.argv = {argv!r}\n"
                       "console.main()\n")
        assert done.returncode == status, done.stderr
        assert "Traceback" not in done.stderr
