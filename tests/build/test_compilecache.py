"""The one compile helper: a build is cached under a key of everything that can change it
(compiler, flags, sources, headers), rebuilt when any of them changes, written under its final
name only when complete, and outside a checkout refused in one line."""
from __future__ import annotations

import shutil
import subprocess

import pytest

from delta6.build import compilecache
from delta6.core import paths
from delta6.core.errors import UserError

GCC = shutil.which("gcc") or "gcc"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """build/<area>/ redirected into the test's folder."""
    out = tmp_path / "build"
    monkeypatch.setattr(compilecache, "build_dir", lambda area: (out / area).mkdir(
        parents=True, exist_ok=True) or out / area)
    return out


@pytest.fixture
def program(tmp_path):
    src = tmp_path / "src"
    inc = tmp_path / "inc"
    src.mkdir()
    inc.mkdir()
    (inc / "answer.h").write_text("#define ANSWER 42\n")
    (src / "local.h").write_text("#define OFFSET 0\n")
    (src / "main.c").write_text('#include <stdio.h>\n#include "answer.h"\n#include "local.h"\n'
                                'int main(void) { printf("%d\\n", ANSWER + OFFSET); return 0; }\n')
    return src, inc


def build(program, flags=("-O1",)):
    src, inc = program
    return compilecache.build_program("answer", [src / "main.c"], compiler=GCC, flags=flags,
                                      include_dirs=[inc], area="test")


def output(exe) -> str:
    return subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.strip()


def test_a_second_build_is_a_lookup(cache, program):
    exe = build(program)
    assert output(exe) == "42" and exe.parent == cache / "test"
    stamp = exe.stat().st_mtime_ns
    assert build(program) == exe and exe.stat().st_mtime_ns == stamp
    assert sorted(p.name for p in exe.parent.iterdir()) == [exe.name]   # no temporary left


@pytest.mark.parametrize("change", ["include_header", "header_beside_source", "source", "flags"])
def test_any_input_changes_the_key(cache, program, change):
    src, inc = program
    first = build(program)
    flags = ("-O1",)
    if change == "include_header":
        (inc / "answer.h").write_text("#define ANSWER 43\n")
    elif change == "header_beside_source":
        (src / "local.h").write_text("#define OFFSET 2\n")
    elif change == "source":
        (src / "main.c").write_text((src / "main.c").read_text().replace("ANSWER +", "ANSWER -"))
    else:
        flags = ("-O2",)
    second = build(program, flags)
    assert second != first and first.exists()
    assert output(second) == {"include_header": "43", "header_beside_source": "44",
                              "source": "42", "flags": "42"}[change]


def test_the_compiler_version_is_part_of_the_key(program, monkeypatch):
    src, inc = program
    key = compilecache.cache_key(GCC, ["-O1"], [src / "main.c"], [inc])
    assert "gcc" in compilecache.compiler_version(GCC).lower()
    assert compilecache.cache_key(GCC, ["-O1"], [src / "main.c"], [inc]) == key
    monkeypatch.setattr(compilecache, "compiler_version", lambda cc: "gcc 99.0")
    assert compilecache.cache_key(GCC, ["-O1"], [src / "main.c"], [inc]) != key


def test_a_failed_build_leaves_nothing_under_the_final_name(cache, program):
    src, _ = program
    (src / "main.c").write_text("int main(void) { return undefined_name; }\n")
    with pytest.raises(compilecache.BuildError, match="undefined_name") as info:
        build(program)
    assert "building answer failed" in str(info.value) and GCC in str(info.value)
    assert list((cache / "test").iterdir()) == []


def test_write_atomically_keeps_the_old_file_when_producing_fails(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")

    def broken(tmp):
        tmp.write_bytes(b"half")
        raise compilecache.BuildError("interrupted")

    with pytest.raises(compilecache.BuildError):
        compilecache.write_atomically(target, broken)
    assert target.read_bytes() == b"old" and sorted(tmp_path.iterdir()) == [target]
    compilecache.write_atomically(target, lambda tmp: tmp.write_bytes(b"new"))
    assert target.read_bytes() == b"new"


def test_missing_tools_and_sources_are_one_line(cache, program, tmp_path):
    with pytest.raises(compilecache.BuildError, match="^no-such-cc not found; apt-get install x$"):
        compilecache.find_tool("no-such-cc", "apt-get install x")
    with pytest.raises(compilecache.BuildError, match="source file not found"):
        compilecache.build_program("x", [tmp_path / "nope.c"], compiler=GCC, area="test")


def test_outside_a_checkout_building_says_so_in_one_line(program, monkeypatch):
    monkeypatch.setattr(paths, "in_checkout", lambda: False)
    with pytest.raises(UserError, match="needs a source checkout") as info:
        build(program)
    assert "\n" not in str(info.value)
