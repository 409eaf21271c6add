"""Build AVR firmware images with Debian's avr-gcc and Arduino core, without an IDE.

PlatformIO cannot fetch its platforms on every machine (CI included), so this module is the
local build the tests, the benchmarks and the virtual board use. It compiles a list of sources
plus the Arduino core for the classic Nano (ATmega328P), with the flags of the Arduino
platform file, and links an ELF; ``size_check`` compiles and links portable sources for
``-mmcu=avrxmega3`` (the ATmega4809's instruction set, which Debian's avr-libc cannot build
a full image for) to report what they cost in flash and RAM there.

Everything is cached under ``build/avr/`` by a hash of the sources, the headers in the
include directories, the flags and the compiler version, so a second build is a lookup and
any change rebuilds. Builds of different designs land in different directories.
"""
from __future__ import annotations

import functools
import hashlib
import os
import re
import shutil
import subprocess
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from delta6.core.errors import UserError

from delta6.core.paths import REPO_ROOT  # noqa: E402
BUILD_ROOT = REPO_ROOT / "build" / "avr"
FIRMWARE = REPO_ROOT / "firmware"
CORE_LIB = FIRMWARE / "lib" / "delta6_core" / "src"
COMMITTED_DESIGN_INCLUDE = FIRMWARE / "include"
ARDUINO_AVR = Path("/usr/share/arduino/hardware/arduino/avr")
APT_HINT = ("install it with: sudo apt-get install --no-install-recommends gcc-avr avr-libc "
            "binutils-avr arduino-core-avr (or run bash tools/bootstrap.sh)")

# Warnings that our own (portable) sources must pass; the Arduino core gets the platform's -w.
OWN_WARNINGS = ("-Wall", "-Wextra", "-Wdouble-promotion", "-Werror")
COMMON = ("-Os", "-g", "-ffunction-sections", "-fdata-sections", "-flto")
CXX_FLAGS = ("-fno-exceptions", "-fno-threadsafe-statics", "-fno-rtti")
# Debian's Arduino core needs DECIMAL_DIG, which gcc 5.4's <float.h> does not define.
CORE_FIX = ("-DDECIMAL_DIG=__DECIMAL_DIG__",)


class ToolchainMissing(UserError):
    """avr-gcc, avr-libc or the Arduino core is not installed."""


class BuildError(UserError):
    """A compiler or linker step failed; the message carries its command and output."""


@dataclass(frozen=True)
class Board:
    """An Arduino-core target that Debian's toolchain builds completely."""

    name: str
    mcu: str
    f_cpu: int
    variant: str
    board_define: str
    flash_bytes: int
    ram_bytes: int


#: The classic Nano: what the emulator runs (simavr knows the ATmega328P, not the 4809).
NANO = Board("nano", "atmega328p", 16_000_000, "eightanaloginputs", "ARDUINO_AVR_NANO",
             flash_bytes=30720, ram_bytes=2048)


@dataclass(frozen=True)
class Sizes:
    """Section sizes in bytes: flash = .text + .data, RAM = .data + .bss + .noinit (static)."""

    text: int
    data: int
    bss: int

    @property
    def flash(self) -> int:
        return self.text + self.data

    @property
    def ram(self) -> int:
        return self.data + self.bss


@dataclass(frozen=True)
class Image:
    elf: Path
    hex: Path | None
    sizes: Sizes
    mcu: str


def _tool(name: str) -> str:
    path = shutil.which(name)
    if not path:
        raise ToolchainMissing(f"{name} not found; {APT_HINT}")
    return path


def _run(cmd: list[str], what: str) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise BuildError(f"{what} failed:\n  {' '.join(cmd)}\n{proc.stderr.strip()}")


@functools.cache   # one `--version` per process, not one per build_image call
def _compiler_version(cc: str) -> str:
    return subprocess.run([cc, "--version"], capture_output=True, text=True).stdout


def _digest(parts: list[str], files: list[Path], include_dirs: list[Path]) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(part.encode() + b"\0")
    for f in files:
        h.update(str(f).encode() + b"\0" + f.read_bytes())
    for d in include_dirs:
        for header in sorted(d.rglob("*.h")):
            h.update(str(header).encode() + b"\0" + header.read_bytes())
    return h.hexdigest()[:16]


def _object_name(src: Path) -> str:
    # Distinct objects for same-named sources in different directories.
    tag = hashlib.sha256(str(src).encode()).hexdigest()[:6]
    return f"{src.stem}-{tag}.o"


def _compile_all(jobs: list[list[str]], what: str) -> None:
    with ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1)) as pool:
        for fut in [pool.submit(_run, cmd, what) for cmd in jobs]:
            fut.result()


def _compile_cmd(src: Path, obj: Path, mcu: str, flags: list[str]) -> list[str]:
    suffix = src.suffix.lower()
    if suffix in (".cpp", ".cc"):
        return [_tool("avr-g++"), "-c", *COMMON, *CXX_FLAGS, f"-mmcu={mcu}", *flags,
                str(src), "-o", str(obj)]
    if suffix == ".c":
        return [_tool("avr-gcc"), "-c", *COMMON, f"-mmcu={mcu}", *flags, str(src), "-o", str(obj)]
    if suffix == ".s":
        return [_tool("avr-gcc"), "-c", "-x", "assembler-with-cpp", "-flto", f"-mmcu={mcu}",
                *flags, str(src), "-o", str(obj)]
    raise BuildError(f"do not know how to compile {src}")


def arduino_core(board: Board = NANO) -> Path:
    """The Arduino core of ``board`` as a static library (LTO objects), cached."""
    cores = ARDUINO_AVR / "cores" / "arduino"
    variant = ARDUINO_AVR / "variants" / board.variant
    if not cores.is_dir():
        raise ToolchainMissing(f"Arduino core not found at {cores}; {APT_HINT}")
    sources = sorted(p for p in cores.iterdir() if p.suffix in (".c", ".cpp", ".S"))
    defines = _board_defines(board)
    flags = [*defines, *CORE_FIX, "-w", f"-I{cores}", f"-I{variant}"]
    key = _digest([_compiler_version(_tool("avr-gcc")), *flags], sources, [])
    out = BUILD_ROOT / f"core-{board.name}-{key}"
    archive = out / "core.a"
    if archive.exists():
        return archive
    objdir = out / "obj"
    objdir.mkdir(parents=True, exist_ok=True)
    jobs = []
    objects = []
    for src in sources:
        obj = objdir / _object_name(src)
        extra = ["-std=gnu11"] if src.suffix == ".c" else (
            ["-std=gnu++11", "-fpermissive"] if src.suffix == ".cpp" else [])
        jobs.append(_compile_cmd(src, obj, board.mcu, [*extra, *flags]))
        objects.append(obj)
    _compile_all(jobs, "compiling the Arduino core")
    tmp = out / "core.a.tmp"
    tmp.unlink(missing_ok=True)
    _run([_tool("avr-gcc-ar"), "rcs", str(tmp), *map(str, objects)], "archiving the Arduino core")
    tmp.replace(archive)
    return archive


def _board_defines(board: Board) -> list[str]:
    return [f"-DF_CPU={board.f_cpu}L", "-DARDUINO=10819", f"-D{board.board_define}",
            "-DARDUINO_ARCH_AVR"]


def _define_flags(defines) -> list[str]:
    out = []
    for d in defines:
        out.append(f"-D{d}" if not str(d).startswith("-D") else str(d))
    return out


def build_image(name: str, sources, include_dirs=(), defines=(), *, board: Board = NANO,
                arduino: bool = True, cxx_std: str = "gnu++14", extra_flags=(),
                link_flags=(), out_dir: Path | None = None) -> Image:
    """Compile ``sources`` (C++/C/asm) for ``board`` and link an ELF (+ Intel HEX), cached.

    ``include_dirs`` come first on the include path (put a design's generated-header
    directory here to build for that design); ``defines`` are ``NAME`` or ``NAME=VALUE``;
    ``extra_flags`` go to every compile of ``sources``. With ``arduino`` the Arduino core is
    linked in and its headers are on the path.
    Returns the image with its section sizes. Raises :class:`ToolchainMissing` or
    :class:`BuildError` with the failing command.
    """
    sources = [Path(s).resolve() for s in sources]
    includes = [Path(d).resolve() for d in include_dirs]
    for src in sources:
        if not src.is_file():
            raise BuildError(f"source file not found: {src}")
    core_flags = []
    if arduino:
        core_flags = [*_board_defines(board), f"-I{ARDUINO_AVR / 'cores' / 'arduino'}",
                      f"-I{ARDUINO_AVR / 'variants' / board.variant}"]
    flags = [*(f"-I{d}" for d in includes), *_define_flags(defines), *core_flags, *extra_flags]
    cc = _tool("avr-gcc")
    key = _digest([_compiler_version(cc), board.mcu, cxx_std, *flags, *link_flags, str(arduino)],
                  sources, includes)
    out = Path(out_dir) if out_dir else BUILD_ROOT / f"{name}-{key}"
    elf = out / f"{name}.elf"
    hex_path = out / f"{name}.hex"
    stamp = out / ".key"
    if elf.exists() and hex_path.exists() and stamp.exists() and stamp.read_text() == key:
        return Image(elf, hex_path, elf_sizes(elf), board.mcu)
    core = arduino_core(board) if arduino else None
    objdir = out / "obj"
    objdir.mkdir(parents=True, exist_ok=True)
    jobs, objects = [], []
    for src in sources:
        obj = objdir / _object_name(src)
        std = [f"-std={cxx_std}"] if src.suffix in (".cpp", ".cc") else (
            ["-std=gnu11"] if src.suffix == ".c" else [])
        jobs.append(_compile_cmd(src, obj, board.mcu, [*std, *OWN_WARNINGS, *flags]))
        objects.append(obj)
    _compile_all(jobs, f"compiling {name}")
    link = [cc, "-Os", "-g", "-flto", "-fuse-linker-plugin", "-Wl,--gc-sections",
            f"-mmcu={board.mcu}", *link_flags, "-o", str(elf), *map(str, objects)]
    if core:
        link.append(str(core))
    link += [f"-L{out}", "-lm"]
    _run(link, f"linking {name}")
    _run([_tool("avr-objcopy"), "-O", "ihex", "-R", ".eeprom", str(elf), str(hex_path)],
         f"making the HEX file of {name}")
    stamp.write_text(key)
    return Image(elf, hex_path, elf_sizes(elf), board.mcu)


def size_check(name: str, sources, include_dirs=(), defines=(), *,
               mcu: str = "avrxmega3", cxx_std: str = "gnu++14") -> Image:
    """Compile and link ``sources`` for ``mcu`` without the Arduino core, to tell what they
    cost in flash and RAM. The sources must provide ``main``. For a bare instruction set
    such as avrxmega3 (Debian's avr-libc has no ATmega4809) the image has no start-up code:
    it is for sizes only, never for running."""
    board = Board(f"bare-{mcu}", mcu, f_cpu=0, variant="", board_define="", flash_bytes=0,
                  ram_bytes=0)
    # Without a device <avr/io.h> warns (-Wno-cpp); main is the entry point so that
    # --gc-sections keeps it when there is no start-up code to reference it.
    return build_image(name, sources, include_dirs, defines, board=board, arduino=False,
                       cxx_std=cxx_std, extra_flags=("-Wno-cpp",), link_flags=("-Wl,-e,main",))


_SECTION = re.compile(r"^(\.\w+)\s+(\d+)\s+\d+", re.M)


def elf_sizes(elf: Path) -> Sizes:
    """Section sizes of an AVR ELF (avr-size -A)."""
    proc = subprocess.run([_tool("avr-size"), "-A", str(elf)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise BuildError(f"avr-size failed on {elf}: {proc.stderr.strip()}")
    sections = {m.group(1): int(m.group(2)) for m in _SECTION.finditer(proc.stdout)}
    return Sizes(text=sections.get(".text", 0), data=sections.get(".data", 0),
                 bss=sections.get(".bss", 0) + sections.get(".noinit", 0))


def design_build_dir(design_name: str) -> Path:
    """``build/designs/NAME``: where ``delta6 codegen --build`` puts a design's header and
    image, one directory per design, so building a variant never touches the committed
    header."""
    return REPO_ROOT / "build" / "designs" / design_name


def design_include_dir(design_name: str) -> Path:
    return design_build_dir(design_name) / "include"
