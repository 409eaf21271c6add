"""The one compile helper: every build of the project (native libraries and executables, the
simavr tools, AVR images) finds its tools, keys its cache and writes its outputs here.

A build's output lives under the checkout's ``build/<area>/`` named by a key that covers
everything that can change the result: the compiler (its path and ``--version``), every flag,
and the path and bytes of every source and of every header it may include (the ``*.h`` files
under its include directories and beside its sources, plus any other dependency named). So a
second build is a lookup and any change rebuilds. Outputs are written to a temporary name and
renamed into place, so an interrupted or concurrent build never leaves a half-written file
under the final name. Building needs the firmware and tool sources of a checkout; from an
installed copy it says so in one line (:func:`delta6.core.paths.checkout`).
"""
from __future__ import annotations

import functools
import hashlib
import shutil
import subprocess
from collections.abc import Iterable
from pathlib import Path

from delta6.core import paths
from delta6.core.errors import UserError
from delta6.core.outputs import write_atomically


class BuildError(UserError):
    """A compiler or linker step failed, or a tool is missing; the message says which."""


def find_tool(name: str, hint: str, error: type[UserError] = BuildError) -> str:
    """The path of the program ``name``, or ``error`` saying what to install (``hint``)."""
    path = shutil.which(name)
    if not path:
        raise error(f"{name} not found; {hint}")
    return path


@functools.cache   # one `--version` per compiler and process
def compiler_version(compiler: str) -> str:
    return subprocess.run([compiler, "--version"], capture_output=True, text=True).stdout


def headers(dirs: Iterable[Path]) -> list[Path]:
    """Every ``*.h`` under ``dirs`` (recursively), sorted, each once."""
    found = set()
    for d in dirs:
        if Path(d).is_dir():
            found.update(Path(d).rglob("*.h"))
    return sorted(found)


def cache_key(compiler: str, args: Iterable[str], sources: Iterable[Path],
              include_dirs: Iterable[Path] = (), depends: Iterable[Path] = ()) -> str:
    """16 hex digits over the compiler and its version, ``args`` (every flag: not the output
    path), the sources, and the headers under ``include_dirs`` and beside the sources."""
    sources = [Path(s) for s in sources]
    h = hashlib.sha256()
    for part in (compiler, compiler_version(compiler), *args):
        h.update(str(part).encode() + b"\0")
    dirs = [*map(Path, include_dirs), *{s.parent for s in sources}]
    for f in [*sources, *headers(dirs), *map(Path, depends)]:
        h.update(str(f).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def build_dir(area: str) -> Path:
    """``build/<area>/`` of the checkout (created); one line outside a checkout."""
    out = paths.build_dir(area)
    out.mkdir(parents=True, exist_ok=True)
    return out


def run(cmd: list[str], what: str, error: type[UserError] = BuildError) -> None:
    """Run one build step; on failure raise ``error`` with the command and its output."""
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise error(f"{what} failed:\n  {' '.join(map(str, cmd))}\n{proc.stderr.strip()}")


def check_sources(name: str, sources: Iterable[Path], error: type[UserError] = BuildError) -> None:
    paths.checkout()    # firmware and tool sources exist only in a checkout
    for src in sources:
        if not Path(src).is_file():
            raise error(f"building {name}: source file not found: {src}")


def build_program(name: str, sources, *, compiler: str, flags: Iterable[str] = (),
                  include_dirs: Iterable[Path] = (), libs: Iterable[str] = (),
                  depends: Iterable[Path] = (), area: str, suffix: str = "",
                  error: type[UserError] = BuildError) -> Path:
    """Compile and link ``sources`` in one compiler call into ``build/<area>/<name>-<key>``
    + ``suffix`` (an executable, or a shared library with ``-shared`` in ``flags``), cached."""
    sources = [Path(s) for s in sources]
    check_sources(name, sources, error)
    args = [*flags, *(f"-I{d}" for d in include_dirs)]
    key = cache_key(compiler, [*args, *libs], sources, include_dirs, depends)
    out = build_dir(area) / f"{name}-{key}{suffix}"
    if out.exists():
        return out
    return write_atomically(out, lambda tmp: run(
        [compiler, *args, *map(str, sources), "-o", str(tmp), *libs], f"building {name}", error))
