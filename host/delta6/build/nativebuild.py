"""Build the portable firmware core natively (host g++): shared libraries for ctypes and small
test executables.

The firmware core is plain C++ with no Arduino headers, so the same source files that go into
the AVR image compile here: the tests check them against the Python reference, and the
simulated device (``delta6sim://``) runs them. Outputs are cached under ``build/native/`` by
:mod:`delta6.build.compilecache`, so each is built once and any change rebuilds.
"""
from __future__ import annotations

import ctypes
import shutil
from pathlib import Path

from delta6.build import compilecache
from delta6.core.paths import REPO_ROOT as ROOT

FIRMWARE_CORE = ROOT / "firmware" / "lib" / "delta6_core" / "src"
FIRMWARE_NATIVE = ROOT / "firmware" / "native"
CXX = shutil.which("g++") or "g++"
# Strict warnings: the same code must also pass avr-gcc 5.4, so keep it boring C++14.
COMMON_FLAGS = ("-std=c++14", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
                "-fno-exceptions", "-fno-rtti")
SHARED_FLAGS = ("-fPIC", "-shared")
BASE_FLAGS = COMMON_FLAGS[:2] + SHARED_FLAGS + COMMON_FLAGS[2:]


class NativeBuildError(compilecache.BuildError):
    """The C++ compiler is missing or the sources do not build; the message says which."""


def _build(name: str, suffix: str, flags: tuple[str, ...], sources, include_dirs) -> Path:
    cxx = compilecache.find_tool(CXX, "install it with: sudo apt-get install g++",
                                 NativeBuildError)
    return compilecache.build_program(name, sources, compiler=cxx, flags=flags,
                                      include_dirs=include_dirs, area="native", suffix=suffix,
                                      error=NativeBuildError)


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

