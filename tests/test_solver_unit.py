"""Build and run the native C++ unit tests of the solver core under AddressSanitizer and
UndefinedBehaviorSanitizer, as C++11 (the oldest dialect the firmware must build with)."""
from __future__ import annotations

import hashlib
import subprocess

from native import BUILD, CXX, ROOT

CORE = ROOT / "firmware" / "lib" / "delta6_core" / "src"
SOURCES = [ROOT / "tests" / "native" / "solver_unit_test.cpp", CORE / "delta6_solver.cpp"]
INCLUDES = [CORE, ROOT / "firmware" / "include"]
FLAGS = ["-std=c++11", "-O1", "-g", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
         "-fno-exceptions", "-fno-rtti", "-fsanitize=address,undefined",
         "-fno-sanitize-recover=all", "-fno-omit-frame-pointer"]


def build() -> str:
    digest = hashlib.sha256(" ".join(FLAGS).encode())
    for path in [*SOURCES, *(p for d in INCLUDES for p in sorted(d.rglob("*.h")))]:
        digest.update(path.read_bytes())
    exe = BUILD / f"solver-unit-{digest.hexdigest()[:16]}"
    if not exe.exists():
        BUILD.mkdir(parents=True, exist_ok=True)
        cmd = [CXX, *FLAGS, *(f"-I{d}" for d in INCLUDES), *map(str, SOURCES), "-o", str(exe)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0, f"{' '.join(cmd)}\n{proc.stderr}"
    return str(exe)


def test_solver_unit_tests_pass_under_sanitizers():
    proc = subprocess.run([build()], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.strip().endswith("all passed")
    assert "runtime error" not in proc.stderr   # UBSan reports, should they not abort
