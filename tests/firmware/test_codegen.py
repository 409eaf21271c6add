"""`delta6 codegen`: the generated design header is deterministic and the committed one is
up to date with designs/delta6.toml; the wire layout header is up to date with the protocol's
tables and the core writes no wire number of its own."""
from __future__ import annotations

import re
import shutil
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.cli import main
from delta6.core.design import load
from delta6.link import protocol as P
from delta6_codegen import render, render_wire
from delta6_codegen.design_header import c_float
from delta6_codegen.wire_header import HEADER_RELPATH as WIRE_RELPATH
from delta6_codegen.wire_header import camel

from conftest import DESIGN_FILES, DESIGNS, ROOT

COMMITTED = ROOT / "firmware" / "include" / "generated" / "delta6_design.h"


def test_committed_header_is_up_to_date():
    expected = render(load(DESIGNS / "delta6.toml"), "designs/delta6.toml")
    assert COMMITTED.read_text(encoding="utf-8") == expected, (
        "firmware/include/generated/delta6_design.h is out of date with designs/delta6.toml: "
        "run `delta6 codegen designs/delta6.toml` and commit the result")


def test_same_bytes_from_any_working_directory(tmp_path, monkeypatch):
    out = tmp_path / "generated" / "delta6_design.h"
    committed = COMMITTED.read_bytes()          # read first: nothing here may rewrite it
    monkeypatch.chdir(ROOT)
    assert main(["codegen", "designs/delta6.toml", "--check"]) == 0
    assert main(["codegen", "designs/delta6.toml", "-o", str(out)]) == 0
    first = out.read_bytes()
    monkeypatch.chdir(tmp_path)
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(out)]) == 0
    assert out.read_bytes() == first
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "--check", "-o", str(COMMITTED)]) == 0
    # The banner names -o; the rest is the committed header's, which is left as it was.
    assert first.splitlines()[4:] == committed.splitlines()[4:]
    assert COMMITTED.read_bytes() == committed


def test_a_calibration_or_model_leaves_the_design_header_as_delta6_codegen_writes_it(
        tmp_path, monkeypatch):
    """The design header is the same for every calibration and model: its banner names the
    design alone, so flashing or generating a calibrated shipped design leaves the committed
    header byte for byte (it said `... --calibration unit.toml`, and the tree was dirty)."""
    from delta6.core import calibration as calibration_mod
    cal_path = calibration_mod.save(
        calibration_mod.neutral(load(DESIGNS / "delta6.toml"), name="unit-7"),
        tmp_path / "unit.toml")
    committed = COMMITTED.read_bytes()
    out = tmp_path / "generated" / "delta6_design.h"
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "--calibration", str(cal_path),
                 "-o", str(out)]) == 0
    plain = tmp_path / "plain" / "generated" / "delta6_design.h"
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(plain)]) == 0
    assert out.read_bytes().replace(str(out).encode(), b"") == \
        plain.read_bytes().replace(str(plain).encode(), b"")
    assert b"--calibration" not in out.read_bytes()
    # ... and the calibration header names the whole command.
    assert b"--calibration" in out.with_name("delta6_calibration.h").read_bytes()
    assert COMMITTED.read_bytes() == committed


def test_banners_name_the_command_as_it_can_be_run_again(tmp_path, capsys, monkeypatch):
    """A user's design outside the checkout: the banner names its full path and every flag
    (it said `delta6 codegen tiny.toml`, dropping --build and -o) and claims no test checks
    it; --check names the same command and calls a missing header missing."""
    design = tmp_path / "my designs" / "tiny.toml"
    design.parent.mkdir()
    design.write_text(re.sub(r"(?m)^name = .*$", 'name = "tiny"',
                             (DESIGNS / "delta6.toml").read_text()))
    out = tmp_path / "out" / "generated" / "delta6_design.h"
    monkeypatch.chdir(tmp_path)
    command = f"delta6 codegen '{design}' -o {out}"
    capsys.readouterr()
    assert main(["codegen", str(design), "-o", str(out), "--check"]) == 1
    assert capsys.readouterr().err.strip().endswith(f"is missing; run: {command}")
    assert main(["codegen", str(design), "-o", str(out)]) == 0
    banner = out.read_text().splitlines()[:4]
    assert banner[1] == f"// Written by `{command}` from the design file {design}."
    assert "test_codegen" not in " ".join(banner)
    assert main(["codegen", str(design), "-o", str(out), "--check"]) == 0
    assert main(["codegen", str(design), "--build", "--check"]) == 1
    assert f"run: delta6 codegen '{design}' --build" in capsys.readouterr().err
    # The committed header alone carries the test's promise.
    committed = COMMITTED.read_text().splitlines()[:4]
    assert "tests/firmware/test_codegen.py fails" in " ".join(committed)


def test_calibration_and_model_banners_make_no_promise_about_committed_headers(baseline):
    from delta6_codegen import render_calibration

    from support.calibrations import random_calibration
    text = render_calibration(baseline, random_calibration(baseline, 1), "designs/delta6.toml",
                              "/tmp/unit.toml", command="delta6 flash --port P --design "
                              "designs/delta6.toml --calibration /tmp/unit.toml")
    banner = " ".join(text.splitlines()[:5])
    assert "`delta6 flash --port P --design designs/delta6.toml --calibration /tmp/unit.toml`" \
        in banner
    assert "committed" not in banner and "tests/" not in banner


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


def test_a_design_whose_counts_the_wire_can_lose_gets_a_note(tmp_path, capsys):
    """A flat design (no rest angle: the links start straight) moves the plate by less than a
    force LSB per count somewhere in its box; its firmware is still written, with a note."""
    text = (DESIGNS / "delta6.toml").read_text()
    flat = tmp_path / "flat.toml"
    flat.write_text(re.sub(r"(?m)^name = .*$", 'name = "flat"',
                           re.sub(r"(?m)^theta_offset_rad = .*$", "theta_offset_rad = 0.0",
                                  text)))
    capsys.readouterr()
    assert main(["codegen", str(flat), "-o", str(tmp_path / "g" / "delta6_design.h")]) == 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "note: design flat" in err, err
    assert "a force step of joints 1..3 (margin 0." in err and "moment" not in err
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o",
                 str(tmp_path / "s" / "delta6_design.h")]) == 0
    assert capsys.readouterr().err == ""


def slip_design(tmp_path):
    """The paper's design with its lengths in metres and its spring rate in N*mm/rad."""
    text = (DESIGNS / "delta6.toml").read_text()
    for key in ("a_mm", "b_mm", "c_mm", "la_mm", "lb_mm"):
        text = re.sub(rf"(?m)^{key} = ([0-9.]+)",
                      lambda m: f"{key} = {float(m.group(1)) / 1000:g}", text)
    text = re.sub(r"(?m)^k_nm_per_rad = .*$", "k_nm_per_rad = 639.236", text)
    slip = tmp_path / "slip.toml"
    slip.write_text(re.sub(r"(?m)^name = .*$", 'name = "slip"', text))
    return slip


def test_values_in_another_unit_get_a_note_and_no_firmware(tmp_path, capsys):
    """Lengths in metres and a rate in N*mm/rad make a valid but absurd design: the design
    tools take it with a line naming each suspect value; codegen refuses it in one line
    before writing anything, unless told it is meant. The shipped designs get none."""
    from delta6.core.design import unit_slip_notes
    assert not [n for path in DESIGN_FILES for n in unit_slip_notes(load(path))]
    slip = slip_design(tmp_path)
    capsys.readouterr()
    assert main(["design", str(slip)]) == 0
    err = capsys.readouterr().err
    assert "a_mm = 0.072 is outside 1..2000 mm (metres or inches?)" in err
    assert "k_nm_per_rad of joint 1 = 639.236 is outside 0.001..100 N*m/rad (N*mm/rad?)" in err
    out = tmp_path / "g" / "delta6_design.h"
    for extra in ([], ["--build"]):
        assert main(["codegen", str(slip), "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "a_mm = 0.072" in err and "--allow-implausible" in err, err
        assert not out.parent.exists()
    assert main(["codegen", str(slip), "-o", str(out), "--allow-implausible"]) == 0
    assert "note: design slip: a_mm = 0.072" in capsys.readouterr().err
    assert out.exists()


@pytest.mark.parametrize("name,value,field", [("la-in-m", "la_mm = 0.040", "la_mm"),
                                               ("k-nmm", "k_nm_per_rad = 639.236",
                                                "k_nm_per_rad")])
def test_flash_and_virtual_refuse_a_unit_slip_before_writing(tmp_path, capsys, name, value,
                                                             field):
    """flash and virtual build firmware too: the same refusal, before any header is written or
    the emulator started."""
    key = value.split(" = ")[0]
    text = re.sub(rf"(?m)^{key} = .*$", value, (DESIGNS / "delta6.toml").read_text())
    design = tmp_path / "slip.toml"
    design.write_text(re.sub(r"(?m)^name = .*$", f'name = "{name}"', text))
    project = tmp_path / "firmware"
    project.mkdir()
    (project / "platformio.ini").write_text("[platformio]\n")
    capsys.readouterr()
    for argv in (["flash", "--port", "delta6sim://", "--firmware-dir", str(project),
                  "--design", str(design), "--pio", "/bin/false"],
                 ["virtual", "--design", str(design), "--duration", "1"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and field in err and "no firmware is built" in err, err
    assert not (project / "include").exists()


def test_flash_prints_the_design_notes_too(tmp_path, capsys):
    """A soft note (the wire loses steps of a flat design) is printed by flash as by codegen."""
    text = (DESIGNS / "delta6.toml").read_text()
    flat = tmp_path / "flat.toml"
    flat.write_text(re.sub(r"(?m)^name = .*$", 'name = "flat"',
                           re.sub(r"(?m)^theta_offset_rad = .*$", "theta_offset_rad = 0.0",
                                  text)))
    project = tmp_path / "firmware"
    project.mkdir()
    (project / "platformio.ini").write_text("[platformio]\n")
    capsys.readouterr()
    assert main(["flash", "--port", "p", "--firmware-dir", str(project), "--design", str(flat),
                 "--dry-run"]) == 0
    assert "note: design flat: one encoder count" in capsys.readouterr().err


def test_unwritable_output_is_a_user_error(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(blocker / "x.h")]) == 2
    assert "cannot write" in capsys.readouterr().err


# --- the wire layout header ----------------------------------------------------------------

WIRE = ROOT / WIRE_RELPATH


def test_committed_wire_header_is_up_to_date():
    assert WIRE.read_text(encoding="utf-8") == render_wire(), (
        f"{WIRE_RELPATH} is out of date with delta6.link.protocol: run `delta6 codegen --wire` "
        "and commit the result")


def test_wire_check_reports_a_stale_header_and_the_fix(tmp_path, capsys):
    assert main(["codegen", "--wire", "--check"]) == 0
    stale = tmp_path / "delta6_wire.h"
    size = P.RECORD_SIZES[P.RecordType.INFO]
    stale.write_text(WIRE.read_text().replace(f"kInfoSize = {size}", f"kInfoSize = {size - 1}"))
    assert main(["codegen", "--wire", "--check", "-o", str(stale)]) == 1
    assert "run: delta6 codegen --wire" in capsys.readouterr().err
    assert main(["codegen", "--wire", "-o", str(stale)]) == 0
    assert stale.read_bytes() == WIRE.read_bytes()


def test_wire_takes_no_design_and_a_design_is_otherwise_needed(capsys):
    assert main(["codegen", "--wire", str(DESIGNS / "delta6.toml")]) == 2
    assert main(["codegen"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no design file" in err[0] and "--wire" in err[1]


def test_wire_header_holds_every_table_entry():
    """Every enum member, record field and command of delta6.link.protocol has its constant,
    with its value; the banner names the command that regenerates it."""
    text = render_wire()
    assert "GENERATED FILE - DO NOT EDIT" in text.splitlines()[0]
    assert "`delta6 codegen --wire`" in text.splitlines()[1]
    consts = dict(re.findall(r"^const \w+ (k\w+) = (0x[0-9A-F]+|-?\d+)U?L?;", text, re.M))
    value = {name: int(v, 0) for name, v in consts.items()}
    for kind, layout in P.RECORD_LAYOUTS.items():
        name = "k" + camel(kind.name)
        assert value[name] == kind and value[name + "Size"] == layout.size
        for f in layout.fields:
            assert value[f"{name}Off{camel(f.name)}"] == layout.offsets[f.name]
    for command, size in P.COMMAND_SIZES.items():
        assert value["kCmd" + camel(command.name)] == command
        assert value["kCmd" + camel(command.name) + "Size"] == size
    for enum_type, prefix in [(P.Mode, "kMode"), (P.NackReason, "kNack"),
                              (P.EventCode, "kEvent"), (P.ConfigProblem, "kConfig")]:
        for member in enum_type:
            assert value[prefix + camel(member.name)] == member
    for flag in P.Status:
        assert f"kStatus{camel(flag.name)} = 1u << {int(flag).bit_length() - 1};" in text
    for field in P.CONFIG_LAYOUT.fields:
        assert value[f"kConfigOff{camel(field.name)}"] == P.CONFIG_LAYOUT.offsets[field.name]
    assert (value["kConfigBlobSize"], value["kConfigMagic"]) == (P.CONFIG_BLOB_SIZE,
                                                                 P.CONFIG_MAGIC)
    assert (value["kMaxValue"], value["kInvalidValue"]) == (P.MAX_VALUE, P.INVALID_VALUE)
    assert Fraction(value["kLinkBudgetNumerator"], value["kLinkBudgetDivisor"]) == (
        P.LINK_BUDGET / P.BITS_PER_BYTE)


def test_core_sources_write_no_wire_numbers_themselves():
    """No hand-copied offsets (``p + 74``) or type bytes in the device core: the offsets and
    types come from the generated header by name."""
    core = ROOT / "firmware" / "lib" / "delta6_core" / "src"
    for name in ("delta6_device.cpp", "delta6_protocol.cpp"):
        code = re.sub(r"//.*", "", (core / name).read_text(encoding="utf-8"))
        assert not re.findall(r"\b(?:p|blob) \+ \d+", code), name
        assert not re.findall(r"\b0x[89][0-9A-Fa-f]\b", code), name
    # Records and the blob are built field by field (putU16 and friends index their bytes).
    device = (core / "delta6_device.cpp").read_text(encoding="utf-8")
    assert not re.findall(r"\b(?:p|blob)\[\d+\]", device)


def test_build_with_a_header_elsewhere_is_refused_before_writing(tmp_path, capsys):
    header = tmp_path / "x.h"
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(header), "--build"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--build needs the header at" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_calibration_and_model_names_are_labels_the_headers_hold_exactly(tmp_path):
    # A label is any printable ASCII: quotes, backslashes and "??/" (a trigraph: a backslash
    # before C++17) must come out of the C strings unchanged.
    import json
    import subprocess

    from delta6.core import calibration as C

    from support.onchip import calibration_and_model
    name = 'a"b\\c??/d e'
    cal, cal_path, _, model_path = calibration_and_model(load(DESIGNS / "delta6.toml"),
                                                          tmp_path)
    C.save(cal.with_(name=name), cal_path)
    data = json.loads(model_path.read_text())
    data["name"] = data["calibration"]["name"] = name
    data["calibration"]["hash"] = f"0x{C.load(cal_path).hash32():08x}"
    model_path.write_text(json.dumps(data))
    header = tmp_path / "out" / "generated" / "delta6_design.h"
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "--calibration", str(cal_path),
                 "--model", str(model_path), "-o", str(header)]) == 0
    program = tmp_path / "names.cpp"
    program.write_text('#include <stdio.h>\n#include "generated/delta6_calibration.h"\n'
                       '#include "generated/delta6_model.h"\n'
                       "int main() { puts(delta6::calibration::kName); "
                       "puts(delta6::model::kName); return 0; }\n")
    exe = tmp_path / "names"
    subprocess.run(["g++", "-std=c++11", "-trigraphs", "-Werror", f"-I{tmp_path / 'out'}",
                    f"-I{ROOT / 'firmware' / 'lib' / 'delta6_core' / 'src'}",
                    f"-I{ROOT / 'firmware' / 'include'}", str(program), "-o", str(exe)],
                   check=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    assert out == f"{name}\n{name}\n"


# --- what codegen replaces or removes ------------------------------------------------------

@pytest.mark.parametrize("name", ["delta6_calibration.h", "delta6_model.h"])
def test_a_design_header_named_as_a_companion_is_refused(tmp_path, capsys, name):
    """Written there, it was then removed as a stale calibration header (exit 0, an empty
    folder), or replaced by the calibration's or the model's header."""
    from support.onchip import calibration_and_model
    _, cal_path, _, model_path = calibration_and_model(load(DESIGNS / "delta6.toml"), tmp_path)
    out = tmp_path / "out" / name
    out.parent.mkdir()
    for extra in ([], ["--calibration", str(cal_path), "--model", str(model_path)]):
        capsys.readouterr()
        assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "name the design header otherwise" in err, err
        assert list(out.parent.iterdir()) == []


def test_headers_codegen_did_not_write_are_neither_replaced_nor_removed(tmp_path, capsys):
    """A hand-written delta6_calibration.h or delta6_model.h next to the design header (the
    firmware compiles it in when present) was deleted; one at -o was overwritten. Refused
    before the first write; generated ones are replaced and removed as before."""
    from delta6.core import calibration as calibration_mod
    cal_path = calibration_mod.save(
        calibration_mod.neutral(load(DESIGNS / "delta6.toml"), name="unit-7"),
        tmp_path / "unit.toml")
    folder = tmp_path / "generated"
    folder.mkdir()
    out = folder / "d.h"
    for mine, extra in (("delta6_calibration.h", []), ("delta6_model.h", []),
                        ("delta6_calibration.h", ["--calibration", str(cal_path)]),
                        ("d.h", [])):
        (folder / mine).write_text("// my own header\n#define MINE 1\n")
        capsys.readouterr()
        assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "not a header delta6 codegen wrote" in err, err
        assert sorted(p.name for p in folder.iterdir()) == [mine]
        assert (folder / mine).read_text().startswith("// my own header")
        (folder / mine).unlink()
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "--calibration", str(cal_path),
                 "-o", str(out)]) == 0
    assert sorted(p.name for p in folder.iterdir()) == ["d.h", "delta6_calibration.h"]
    assert main(["codegen", str(DESIGNS / "delta6.toml"), "-o", str(out)]) == 0
    assert "removed" in capsys.readouterr().out
    assert sorted(p.name for p in folder.iterdir()) == ["d.h"]
    wire = tmp_path / "wire.h"
    wire.write_text("// mine\n")
    assert main(["codegen", "--wire", "-o", str(wire)]) == 2
    assert wire.read_text() == "// mine\n"


def test_every_header_starts_with_the_generated_marker(baseline):
    from delta6_codegen import GENERATED_MARKER
    assert render(baseline, "designs/delta6.toml").startswith(GENERATED_MARKER + "\n")
    assert render_wire().startswith(GENERATED_MARKER + "\n")
