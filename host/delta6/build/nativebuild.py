"""Build the portable firmware core natively (host g++): shared libraries for ctypes and small
test executables.

The firmware core is plain C++ with no Arduino headers, so the same source files that go into
the AVR image compile here: the tests check them against the Python reference, and the
simulated device (``delta6sim://``) runs them. Outputs are cached under ``build/native/`` by a
hash of sources, headers and flags, so each is built once and a changed source always rebuilds.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
from pathlib import Path

from delta6.core.errors import UserError

from delta6.core.paths import REPO_ROOT as ROOT  # noqa: E402
BUILD = ROOT / "build" / "native"
FIRMWARE_CORE = ROOT / "firmware" / "lib" / "delta6_core" / "src"
FIRMWARE_NATIVE = ROOT / "firmware" / "native"
CXX = shutil.which("g++") or "g++"
# Strict warnings: the same code must also pass avr-gcc 5.4, so keep it boring C++14.
COMMON_FLAGS = ("-std=c++14", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
                "-fno-exceptions", "-fno-rtti")
SHARED_FLAGS = ("-fPIC", "-shared")
BASE_FLAGS = COMMON_FLAGS[:2] + SHARED_FLAGS + COMMON_FLAGS[2:]


class NativeBuildError(UserError):
    """The C++ compiler is missing or the sources do not build; the message says which."""


def _build(name: str, suffix: str, flags: tuple[str, ...], sources, include_dirs) -> Path:
    sources = [Path(s) for s in sources]
    includes = [Path(d) for d in include_dirs]
    missing = [str(s) for s in sources if not s.exists()]
    if missing:
        raise NativeBuildError(f"native build of {name}: source {missing[0]} not found (the "
                               "simulated device needs a checkout of the repository)")
    digest = hashlib.sha256()
    for part in (*flags, *map(str, includes)):
        digest.update(part.encode())
    for src in sources:
        digest.update(src.read_bytes())
    for inc in includes:
        for header in sorted(inc.rglob("*.h")):
            digest.update(header.read_bytes())
    out = BUILD / f"{name}-{digest.hexdigest()[:16]}{suffix}"
    if out.exists():
        return out
    if not shutil.which(CXX):
        raise NativeBuildError(f"native build of {name} needs a C++ compiler: {CXX} not found "
                               "(apt-get install g++)")
    BUILD.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"{out.name}.{os.getpid()}.tmp")   # concurrent builds do not collide
    cmd = [CXX, *flags, *(f"-I{d}" for d in includes), *map(str, sources), "-o", str(tmp)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise NativeBuildError(f"native build of {name} failed:\n{' '.join(cmd)}\n{proc.stderr}")
    tmp.replace(out)
    return out


def build_library(name: str, sources, include_dirs=(), flags: tuple[str, ...] = ()) -> Path:
    """Compile ``sources`` into ``build/native/<name>-<hash>.so`` (cached) and return its path."""
    return _build(name, ".so", (*BASE_FLAGS, *flags), sources, include_dirs)


def load_library(name: str, sources, include_dirs=(), flags: tuple[str, ...] = ()) -> ctypes.CDLL:
    return ctypes.CDLL(str(build_library(name, sources, include_dirs, flags)))


def build_executable(name: str, sources, include_dirs=(), flags: tuple[str, ...] = ()) -> Path:
    """Compile ``sources`` into the executable ``build/native/<name>-<hash>`` (cached)."""
    return _build(name, "", (*COMMON_FLAGS, *flags), sources, include_dirs)


def core_sources() -> list[Path]:
    """The portable firmware core's protocol and device sources, with the device's wrench
    pipeline (low-pass filter, tool frame); not the solver's."""
    return [FIRMWARE_CORE / f"delta6_{part}.cpp"
            for part in ("crc16", "cobs", "protocol", "filter", "toolframe", "device")]

