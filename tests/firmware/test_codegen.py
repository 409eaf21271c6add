"""`delta6 codegen`: the generated design header is deterministic and the committed one is
up to date with designs/delta6.toml."""
from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.cli import main
from delta6.core.design import load
from delta6_codegen import render
from delta6_codegen.design_header import c_float

from conftest import DESIGN_FILES, DESIGNS, ROOT

COMMITTED = ROOT / "firmware" / "include" / "generated" / "delta6_design.h"


def test_committed_header_is_up_to_date():
    expected = render(load(DESIGNS / "delta6.toml"), "designs/delta6.toml")
    assert COMMITTED.read_text(encoding="utf-8") == expected, (
        "firmware/include/generated/delta6_design.h is out of date with designs/delta6.toml: "
        "run `delta6 codegen designs/delta6.toml` and commit the result")


def test_same_bytes_from_any_working_directory(tmp_path, monkeypatch):
    out_a, out_b = tmp_path / "a.h", tmp_path / "b.h"
    monkeypatch.chdir(ROOT)
    assert main(["codegen", "designs/delta6.toml", "-o", str(out_a)]) == 0
    monkeypatch.chdir(tmp_path)
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(out_b)]) == 0
    assert out_a.read_bytes() == out_b.read_bytes() == COMMITTED.read_bytes()


def test_check_reports_stale_headers(tmp_path, capsys):
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "--check", "-o", str(COMMITTED)]) == 0
    stale = tmp_path / "generated" / "delta6_design.h"
    stale.parent.mkdir()
    stale.write_text(COMMITTED.read_text().replace("kHash = 0x", "kHash = 0x1"))
    assert main(["codegen", str(DESIGNS / "stiff.toml"), "--check", "-o", str(stale)]) == 1
    assert "out of date" in capsys.readouterr().err
    assert main(["codegen", str(DESIGNS / "stiff.toml"), "-o", str(stale)]) == 0
    assert main(["codegen", str(DESIGNS / "stiff.toml"), "--check", "-o", str(stale)]) == 0


@pytest.mark.parametrize("path", DESIGN_FILES, ids=lambda p: p.stem)
def test_header_carries_the_design(path):
    d = load(path)
    text = render(d, f"designs/{path.name}")
    assert text == render(d, f"designs/{path.name}")
    assert f'constexpr char kName[] = "{d.name}";' in text
    assert f"kHash = 0x{d.hash32():08X}UL;" in text
    assert f"`delta6 codegen designs/{path.name}`" in text.splitlines()[1]
    assert "GENERATED FILE - DO NOT EDIT" in text.splitlines()[0]
    # Every float literal is the canonical spelling of a float32 (so it round-trips).
    literals = re.findall(r"(?<![\w.])(-?[0-9]+\.[0-9]*(?:e[-+]?[0-9]+)?|-?[0-9]+e[-+]?[0-9]+)f\b",
                          text)
    assert len(literals) > 300
    for literal in literals:
        assert c_float(float(literal)) == literal + "f"



def test_variants_differ():
    headers = {render(load(p), p.name) for p in DESIGN_FILES}
    assert len(headers) == len(DESIGN_FILES)


@given(st.floats(width=32, allow_nan=False, allow_infinity=False))
def test_float_literals_round_trip(x):
    text = c_float(x)
    assert text.endswith("f")
    assert np.float32(float(text[:-1])) == np.float32(x)


def test_bad_design_is_one_line_and_status_2(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text((DESIGNS / "delta6.toml").read_text().replace("lb_mm = 120.0", "lb_mm = -1"))
    assert main(["codegen", str(bad), "-o", str(tmp_path / "x.h")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "lb_mm" in err
    assert not (tmp_path / "x.h").exists()


def test_unwritable_output_is_a_user_error(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(blocker / "x.h")]) == 2
    assert "cannot write" in capsys.readouterr().err
