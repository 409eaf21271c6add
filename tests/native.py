"""Build firmware sources natively (host g++) into shared libraries for ctypes-driven tests.

The portable firmware core is plain C++ with no Arduino headers, so the same source files
that go into the AVR image compile here and can be checked against the Python reference.
Libraries are cached under build/native/ by a hash of their sources and flags, so a test
session builds each one once and a changed source always rebuilds.
"""
from __future__ import annotations

import ctypes
import hashlib
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUILD = ROOT / "build" / "native"
CXX = shutil.which("g++") or "g++"
# Strict warnings: the same code must also pass avr-gcc 5.4, so keep it boring C++14.
BASE_FLAGS = ("-std=c++14", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror",
              "-Wdouble-promotion", "-fno-exceptions", "-fno-rtti")


def build_library(name: str, sources: list[Path], include_dirs: list[Path] = (),
                  flags: tuple[str, ...] = ()) -> Path:
    """Compile ``sources`` into ``build/native/<name>-<hash>.so`` (cached) and return its path."""
    sources = [Path(s) for s in sources]
    includes = [Path(d) for d in include_dirs]
    digest = hashlib.sha256()
    for part in (*BASE_FLAGS, *flags, *map(str, includes)):
        digest.update(part.encode())
    for src in sources:
        digest.update(src.read_bytes())
    for inc in includes:
        for header in sorted(inc.rglob("*.h")):
            digest.update(header.read_bytes())
    out = BUILD / f"{name}-{digest.hexdigest()[:16]}.so"
    if not out.exists():
        BUILD.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(".tmp.so")
        cmd = [CXX, *BASE_FLAGS, *flags, *(f"-I{d}" for d in includes), *map(str, sources),
               "-o", str(tmp)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"native build of {name} failed:\n{' '.join(cmd)}\n{proc.stderr}")
        tmp.replace(out)
    return out


def load_library(name: str, sources: list[Path], include_dirs: list[Path] = (),
                 flags: tuple[str, ...] = ()) -> ctypes.CDLL:
    return ctypes.CDLL(str(build_library(name, sources, include_dirs, flags)))
