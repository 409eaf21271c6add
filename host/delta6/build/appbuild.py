"""The firmware application (``firmware/src/``): build the ATmega328P image with the local AVR
toolchain, and the avrxmega3 size check of its portable part.

The ATmega328P image is what the classic Nano runs and what the virtual board emulates; the
Nano Every (ATmega4809) image is built by PlatformIO on users' machines (Debian's avr-libc has
no 4809 support). Used by ``delta6 codegen --build``, ``delta6 virtual``, the tests and
``tools/bench_virtual_board.py``.
"""
from __future__ import annotations

from pathlib import Path

from delta6.build import avrbuild, nativebuild

APP_DIR = avrbuild.FIRMWARE / "src"
SIZE_PROBE = avrbuild.FIRMWARE / "native" / "app_size_probe.cpp"
#: Register saves through shared prologue/epilogue routines instead of inline pushes: about
#: 800 bytes less flash for a few cycles per call (under 1 % of a solve), which the
#: ATmega328P's 32 KB need for the calibrated image with a residual model and the wrench
#: pipeline. Compile and link flags (LTO generates the code at link time).
APP_FLAGS = ("-mcall-prologues",)


def solver_sources() -> list[Path]:
    """The wrench path: the solver, the calibrated model and the residual engine (each linked
    in only when a generated header makes the application call it)."""
    return [avrbuild.CORE_LIB / "delta6_solver.cpp", avrbuild.CORE_LIB / "delta6_calibrated.cpp",
            avrbuild.CORE_LIB / "delta6_residual.cpp"]


def app_sources() -> list[Path]:
    """The sketch, the application and both board layers (each compiles only for its MCU),
    plus the portable core."""
    return [*sorted(APP_DIR.glob("*.cpp")), *sorted(APP_DIR.glob("*.S")), *solver_sources(),
            *nativebuild.core_sources()]


def build_app(include_dir: Path | None = None, *, name: str = "delta6-app",
              defines=(), out_dir: Path | None = None) -> avrbuild.Image:
    """The ATmega328P application image for the design whose generated header is under
    ``include_dir``/generated/ (default: the committed header, designs/delta6.toml).
    ``defines``: e.g. ``DELTA6_MAX_RATE_HZ=2000`` (benchmarks) or ``DELTA6_TEST_HOOKS``."""
    include = include_dir if include_dir is not None else avrbuild.COMMITTED_DESIGN_INCLUDE
    return avrbuild.build_image(name, app_sources(),
                                include_dirs=[include, APP_DIR, avrbuild.CORE_LIB],
                                defines=defines, out_dir=out_dir, extra_flags=APP_FLAGS,
                                link_flags=APP_FLAGS)


def size_check_app(mcu: str = "avrxmega3", include_dir: Path | None = None,
                   name: str = "delta6-app-probe") -> avrbuild.Image:
    """The application's portable part (app.cpp, solver, protocol core) on ``mcu`` with a
    do-nothing board layer: what it costs on the ATmega4809's instruction set (``include_dir``:
    a design's generated headers, with or without a calibration). The 4809 board
    layer itself needs the 4809's device headers, which Debian lacks."""
    sources = [APP_DIR / "app.cpp", SIZE_PROBE, *solver_sources(), *nativebuild.core_sources()]
    include = include_dir if include_dir is not None else avrbuild.COMMITTED_DESIGN_INCLUDE
    return avrbuild.size_check(f"{name}-{mcu}", sources,
                               include_dirs=[include, APP_DIR,
                                             avrbuild.CORE_LIB],
                               defines=[f"F_CPU={avrbuild.NANO.f_cpu}UL"], mcu=mcu)
