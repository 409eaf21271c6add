"""Build and run the native C++ unit tests of the solver core under AddressSanitizer and
UndefinedBehaviorSanitizer, as C++11 (the oldest dialect the firmware must build with)."""
from __future__ import annotations

import subprocess

from delta6.build import nativebuild

CORE = nativebuild.FIRMWARE_CORE
SOURCES = [nativebuild.ROOT / "tests" / "native" / "solver_unit_test.cpp", CORE / "delta6_solver.cpp"]
INCLUDES = [CORE, nativebuild.ROOT / "firmware" / "include"]
# Appended to nativebuild's strict warning flags; gcc honours the last -std and -O.
FLAGS = ("-std=c++11", "-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
         "-fno-omit-frame-pointer")


def build() -> str:
    return str(nativebuild.build_executable("solver-unit", SOURCES, INCLUDES, flags=FLAGS))


def test_solver_unit_tests_pass_under_sanitizers():
    proc = subprocess.run([build()], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.strip().endswith("all passed")
    assert "runtime error" not in proc.stderr   # UBSan reports, should they not abort
