"""Build AVR firmware images with Debian's avr-gcc and Arduino core, without an IDE.

PlatformIO cannot fetch its platforms on every machine (CI included), so this module is the
local build the tests, the benchmarks and the virtual board use. It compiles a list of sources
plus the Arduino core for the classic Nano (ATmega328P), with the flags of the Arduino
platform file, and links an ELF; ``size_check`` compiles and links portable sources for
``-mmcu=avrxmega3`` (the ATmega4809's instruction set, which Debian's avr-libc cannot build
a full image for) to report what they cost in flash and RAM there.

Everything is cached under ``build/avr/`` by :mod:`delta6.build.compilecache` (a key over the
compiler version, the flags, the sources and every header they may include), so a second
build is a lookup and any change rebuilds. Builds of different designs land in different
directories.
"""
from __future__ import annotations

import hashlib
import os
import re
import subprocess
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from delta6.build import compilecache
from delta6.core.outputs import write_atomically
from delta6.core.paths import REPO_ROOT

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


BuildError = compilecache.BuildError


class ToolchainMissing(BuildError):
    """avr-gcc, avr-libc or the Arduino core is not installed."""


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


#: The classic Nano: what the emulator runs (simavr knows the ATmega328P, not the 4809). Its
#: budget is the 30,720 B a classic Nano's bootloader leaves; the emulator runs all 32 KB.
NANO = Board("nano", "atmega328p", 16_000_000, "eightanaloginputs", "ARDUINO_AVR_NANO",
             flash_bytes=30720, ram_bytes=2048)


def flash_note(flash: int) -> str:
    """What an ATmega328P image over a classic Nano's budget still fits ('' when within)."""
    if flash <= NANO.flash_bytes:
        return ""
    room = "within" if flash <= 32_768 else "over"
    return (f" (over a classic Nano's {NANO.flash_bytes:,} B with its bootloader; {room} the "
            "32 KB the emulator runs; the Nano Every has 48 KB)")


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
    return compilecache.find_tool(name, APT_HINT, ToolchainMissing)


_run = compilecache.run


#: The linker's words for an image too big for the MCU: "will not fit in region `text'", and
#: usually "region `text' overflowed by N bytes"; static RAM past its end: "section `.data'
#: is not within region `data'".
_NO_FIT = re.compile(r"(?:will not fit in|is not within) region `(\w+)'")
_OVERFLOW = re.compile(r"region `(\w+)' overflowed by (\d+) bytes")
_MEMORY = {"text": "flash", "data": "static RAM"}


def _link(cmd: list[str], name: str, mcu: str) -> None:
    """Link; an image that does not fit is one line (which image, which memory, how many
    bytes over, and why) instead of the linker's dump."""
    try:
        _run(cmd, f"linking {name}")
    except BuildError as exc:
        over = {region: None for region in _NO_FIT.findall(str(exc))}
        over.update((region, int(n)) for region, n in _OVERFLOW.findall(str(exc)))
        if not over:
            raise
        amounts = ", ".join((f"{n:,} bytes " if n else "") + f"over its {_MEMORY.get(r, r)}"
                            for r, n in over.items())
        raise BuildError(f"{name} does not fit the {mcu}: {amounts}. "
                         + " ".join(_CAUSES.get(r, "") for r in over).strip()
                         + " (docs/firmware.md, \"Memory\")") from None


#: Why an image outgrows each memory: the trig tables and the constants live in flash; static
#: RAM holds the state of the calibration's history and the model's windows.
_CAUSES = {
    "text": "The design's joint box sets the size of the trig tables (a wider box, more "
            "flash) and a calibration or a model adds its constants: narrow joint_limit_rad, "
            "or build without them.",
    "data": "Static RAM holds the calibration's history state and the model's windows: a "
            "model with shorter windows, or the image without it, fits.",
}


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
    key = compilecache.cache_key(_tool("avr-gcc"), [board.mcu, *flags], sources, [cores, variant])
    out = compilecache.build_dir("avr") / f"core-{board.name}-{key}"
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
    return write_atomically(archive, lambda tmp: _run(
        [_tool("avr-gcc-ar"), "rcs", str(tmp), *map(str, objects)], "archiving the Arduino core"))


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
    compilecache.check_sources(name, sources)
    core_flags = []
    if arduino:
        core_flags = [*_board_defines(board), f"-I{ARDUINO_AVR / 'cores' / 'arduino'}",
                      f"-I{ARDUINO_AVR / 'variants' / board.variant}"]
    flags = [*(f"-I{d}" for d in includes), *_define_flags(defines), *core_flags, *extra_flags]
    cc = _tool("avr-gcc")
    key = compilecache.cache_key(cc, [board.mcu, cxx_std, *flags, *link_flags, str(arduino)],
                                 sources, includes)
    out = Path(out_dir) if out_dir else compilecache.build_dir("avr") / f"{name}-{key}"
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
    stamp.unlink(missing_ok=True)    # out_dir may hold another key's image: never mix them
    link = [cc, "-Os", "-g", "-flto", "-fuse-linker-plugin", "-Wl,--gc-sections",
            f"-mmcu={board.mcu}", *link_flags, *map(str, objects), *([str(core)] if core else []),
            f"-L{out}", "-lm"]
    write_atomically(elf, lambda tmp: _link([*link, "-o", str(tmp)], name,
                                                         board.mcu))
    write_atomically(hex_path, lambda tmp: _run(
        [_tool("avr-objcopy"), "-O", "ihex", "-R", ".eeprom", str(elf), str(tmp)],
        f"making the HEX file of {name}"))
    write_atomically(stamp, lambda tmp: tmp.write_text(key))
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
    return compilecache.build_dir("designs") / design_name


def design_include_dir(design_name: str) -> Path:
    return design_build_dir(design_name) / "include"
