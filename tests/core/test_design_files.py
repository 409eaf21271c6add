"""Design files: loading, validation, clear one-line errors and exit status 2."""
from __future__ import annotations

import re
import subprocess
import sys
import tomllib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.cli import main
from delta6.core.design import DesignError, load
from delta6.core.workspace import load_checked

from conftest import DESIGN_FILES, DESIGNS

BASE = (DESIGNS / "delta6.toml").read_text()


def write(tmp_path, text, name="d.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def edited(drop=None, set_=None):
    lines = []
    for line in BASE.splitlines():
        key = line.split("=")[0].strip()
        if key == drop:
            continue
        lines.append(line)
    for key, value in (set_ or {}).items():
        lines = [ln for ln in lines if ln.split("=")[0].strip() != key]
        lines.append(f"{key} = {value}")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("path", DESIGN_FILES, ids=lambda p: p.stem)
def test_shipped_designs_load(path):
    d = load(path)
    assert d.name == path.stem
    assert 0 < d.k_nm_per_rad[0] < 1


@pytest.mark.parametrize("text, field, words", [
    (edited(drop="lb_mm"), "lb_mm", "missing"),
    (edited(drop="k_nm_per_rad"), "k_nm_per_rad", "missing"),
    (edited(drop="a_mm", set_={"a_m": 0.072}), "a_m", "a_mm"),
    (edited(drop="theta_offset_rad", set_={"theta_offset_deg": 30}), "theta_offset_deg",
     "theta_offset_rad"),
    (edited(set_={"la_mm": -40}), "la_mm", "> 0"),
    (edited(set_={"b_mm": 0}), "b_mm", "> 0"),
    (edited(set_={"k_nm_per_rad": -0.6}), "k_nm_per_rad", "> 0"),
    (edited(set_={"k_nm_per_rad": "[0.6, 0.6]"}), "k_nm_per_rad", "6 values"),
    (edited(set_={"a_mm": '"72"'}), "a_mm", "number"),
    (edited(set_={"a_mm": "nan"}), "a_mm", "finite"),
    (edited(set_={"b_mm": 80}), "b_mm", "smaller than a_mm"),
    (edited(set_={"lb_mm": 20}), "lb_mm", "no solution"),
    (edited(set_={"theta_offset_rad": 2.0}), "theta_offset_rad", "pi/2"),
    (edited(set_={"joint_limit_rad": 1.7}), "joint_limit_rad", "pi/2"),
    (edited(set_={"colour": '"red"'}), "colour", "unknown key"),
    (edited(set_={"name": '"../../x"'}), "name", "only letters, digits"),
    (edited(set_={"name": '"a/b"'}), "name", "only letters, digits"),
    (edited(set_={"name": '".hidden"'}), "name", "starts with a letter or digit"),
    (edited(set_={"name": '"quote\\"d"'}), "name", "only letters, digits"),
    ("a_mm = [", "file", "TOML"),
])
def test_bad_design_files_are_rejected_with_the_field_named(tmp_path, capsys, text, field, words):
    path = write(tmp_path, text)
    with pytest.raises(DesignError) as info:
        load_checked(path)
    assert info.value.field == field
    message = str(info.value)
    assert f"'{field}'" in message and words in message and "\n" not in message
    assert main(["design", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and field in err and "Traceback" not in err


def test_missing_file(tmp_path, capsys):
    assert main(["design", str(tmp_path / "nope.toml")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_singular_geometry_is_rejected(tmp_path):
    # Links that reach the singular, fully stretched pose inside the box.
    text = edited(set_={"lb_mm": 60, "la_mm": 40, "a_mm": 72, "b_mm": 21.24})
    with pytest.raises(DesignError) as info:
        load_checked(write(tmp_path, text))
    assert info.value.field in ("lb_mm", "la_mm")


def test_command_line_exit_status_and_single_line(tmp_path):
    """The installed entry point, as a user runs it: status 2, one line, no traceback."""
    path = write(tmp_path, edited(set_={"la_mm": -1}))
    proc = subprocess.run([sys.executable, "-m", "delta6", "design", str(path)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stdout == "" and proc.stderr.count("\n") == 1
    assert "la_mm" in proc.stderr


def test_per_joint_stiffness_list(tmp_path):
    d = load(write(tmp_path, edited(set_={"k_nm_per_rad": "[0.6, 0.61, 0.62, 0.63, 0.64, 0.65]"})))
    assert d.k_nm_per_rad == (0.6, 0.61, 0.62, 0.63, 0.64, 0.65)


def test_hash_tracks_physics_not_name(baseline):
    assert baseline.replace(name="other").hash32() == baseline.hash32()
    assert baseline.replace(a_mm=72.001).hash32() != baseline.hash32()
    assert baseline.hash32() == load(DESIGNS / "delta6.toml").hash32()


values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                   st.text(max_size=5), st.booleans(), st.lists(st.floats(-2, 2), max_size=7))


@given(st.dictionaries(st.sampled_from(["name", "a_mm", "b_mm", "c_mm", "la_mm", "lb_mm",
                                        "theta_offset_rad", "k_nm_per_rad", "joint_limit_rad",
                                        "a", "k", "zz"]), values, max_size=10),
       st.booleans())
def test_fuzzed_design_values_never_crash(raw, merge):
    """Whatever the values, loading either gives a valid design or a DesignError."""
    from delta6.core.design import validate
    from delta6.core.workspace import check_solvable
    if merge:
        raw = {**tomllib.loads(BASE), **raw}
    try:
        d = validate(raw)
        check_solvable(d)
    except DesignError as exc:
        assert "\n" not in str(exc)
        return
    assert all(v > 0 for v in d.k_nm_per_rad)


@given(st.binary(max_size=200))
def test_fuzzed_file_bytes_never_crash(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("fuzz") / "d.toml"
    path.write_bytes(data)
    with pytest.raises(DesignError):
        load_checked(path)


def test_a_design_name_cannot_lead_codegen_out_of_the_build_folder(tmp_path, capsys, root):
    """The name becomes build/designs/NAME/: '../../x' would have written outside it."""
    path = write(tmp_path, edited(set_={"name": '"../../x"'}))
    assert main(["codegen", str(path), "--build"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "field 'name'" in err
    assert not (root / "x").exists() and not (root / "build" / "x").exists()


@pytest.mark.parametrize("key, value, words", [
    ("a_mm", 1e300, "must lie in 0.001..100000 mm"),
    ("lb_mm", 1e-9, "must lie in 0.001..100000 mm"),
    ("k_nm_per_rad", 1e12, "must lie in 1e-06..1e+06 N*m/rad"),
    ("joint_limit_rad", 1e-9, "must lie in [0.01, pi/2) rad"),
])
def test_values_the_arithmetic_cannot_carry_are_errors_not_notes(key, value, words):
    """A 1e300 mm arm gave an infinite workspace and full scale (exit 0) and a traceback in
    codegen; a joint box under a count, no joint-limit check on the board."""
    import tomllib

    from delta6.core.design import DesignError, validate
    from delta6.core.paths import DEFAULT_DESIGN
    raw = tomllib.loads(DEFAULT_DESIGN.read_text())
    raw[key] = value
    with pytest.raises(DesignError, match=re.escape(words)):
        validate(raw, "big.toml")


def test_a_byte_order_mark_is_not_an_error(tmp_path, baseline):
    """Some editors start a UTF-8 file with a BOM: the design is read as without it."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + (DESIGNS / "delta6.toml").read_bytes())
    assert load(path) == baseline


def test_side_by_side_shows_per_joint_springs_and_the_joint_box(tmp_path, capsys):
    """The comparison table names a per-joint spring list by its range (it printed nan) and
    has a joint-box column (designs differing only in their box looked alike)."""
    springs = write(tmp_path, edited(set_={"name": '"springs"', "k_nm_per_rad":
                                           "[0.6, 0.61, 0.62, 0.63, 0.64, 0.65]"}))
    narrow = tmp_path / "narrow.toml"
    narrow.write_text(BASE.replace('name = "delta6"', 'name = "narrow"')
                      + "\njoint_limit_rad = 0.2\n")
    assert main(["design", str(springs), str(narrow), "--grid", "3"]) == 0
    out = capsys.readouterr().out
    assert "nan" not in out and "lim rad" in out.splitlines()[0]
    rows = {line.split()[0]: line.split() for line in out.splitlines()[2:4]}
    assert "0.6..0.65" in rows["springs"] and "0.5236" in rows["springs"]
    assert "0.2000" in rows["narrow"] and "0.639236" in rows["narrow"]


@pytest.mark.parametrize("changes, box_is_a_fix", [
    (dict(theta_offset_rad=0.2, joint_limit_rad=1.2), True),    # a wide box reaches it
    (dict(theta_offset_rad=-0.9, joint_limit_rad=0.01), False),  # singular at rest
])
def test_a_singular_box_names_the_box_as_a_fix_when_the_rest_pose_is_fine(baseline, changes,
                                                                          box_is_a_fix):
    from delta6.core.workspace import check_solvable
    with pytest.raises(DesignError) as info:
        check_solvable(baseline.replace(**changes))
    assert info.value.field == "la_mm" and "singular" in str(info.value)
    assert ("reduce joint_limit_rad / change theta_offset_rad" in str(info.value)) == box_is_a_fix
