"""The console script: a Ctrl-C at any moment, from the first import to the exit, ends the
program with one line and status 130, never a traceback and never silently."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from conftest import ROOT


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT / "host")}


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
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=_env(), timeout=60)
    assert done.returncode == 130, done.stderr
    assert done.stderr == "delta6: interrupted (SIGINT)\n"


def test_ctrl_c_after_the_command_finished_still_says_so():
    """A signal between the command's summary and the exit (Python's own handling ends at
    the interpreter's exit: status 130 and no line)."""
    script = ("import os, signal, time, delta6.cli\n"
              "from delta6 import console\n"
              "delta6.cli.main = lambda: print('summary') or 0\n"
              "console.main()\n"
              "os.kill(os.getpid(), signal.SIGINT)\n"
              "time.sleep(5)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=_env(), timeout=60)
    assert done.returncode == 130
    assert done.stdout == "summary\n"
    assert done.stderr == "delta6: interrupted (SIGINT)\n"
