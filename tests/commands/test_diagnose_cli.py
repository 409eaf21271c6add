"""``delta6 diagnose`` as a user runs it: JSON keys, the report, and bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest

from delta6.cli import main
from delta6.link.logfile import LogWriter

from conftest import DESIGNS
from support.logs import synthetic_log

DESIGN = str(DESIGNS / "delta6.toml")


def write_log(path, log, temp=None):
    optional = ("temp_c",) if temp is not None else ()
    with LogWriter(path, {"design": "delta6"}, optional=optional) as w:
        extra = {"temp_c": temp} if temp is not None else {}
        w.write_block(log.t, log.theta, log.wrench, **extra)
    return path


@pytest.fixture(scope="module")
def stiff_log(tmp_path_factory, baseline):
    return write_log(tmp_path_factory.mktemp("logs") / "stiff.csv",
                     synthetic_log(baseline, "stiffness_mismatch", n=6000))


@pytest.mark.slow
def test_json_has_exactly_the_documented_keys(stiff_log, tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["diagnose", str(stiff_log), "--design", DESIGN, "--json", str(out),
                 "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert len(result["baseline_heldout_p99_pct"]) == 6
    assert result["present"] == ["stiffness_mismatch"]
    step = result["ladder"][0]
    assert step["added"] == "stiffness_mismatch" and len(step["heldout_p99_pct"]) == 6
    assert isinstance(step["params"], dict)
    assert step["params"]["k_ratio_error_j1"] == pytest.approx(0.05, abs=0.005)
    names = [c["name"] for c in result["candidates"]]
    assert names[0] == "stiffness_mismatch"
    assert "thermal_drift" not in names and result["skipped"] == ["thermal_drift"]
    for c in result["candidates"]:
        assert len(c["heldout_p99_pct"]) == 6 and isinstance(c["score"], float)
    assert max(step["heldout_p99_pct"]) < 0.5 * min(result["baseline_heldout_p99_pct"])
    text = capsys.readouterr().out
    assert "stiffness_mismatch" in text and "held-out p99" in text


@pytest.mark.slow
def test_report_directory_has_the_report_and_plots(stiff_log, tmp_path):
    out = tmp_path / "rep"
    assert main(["diagnose", str(stiff_log), "--design", DESIGN, "--report", str(out),
                 "--quiet"]) == 0
    report = (out / "report.md").read_text()
    for name in ("ladder", "cross_axis", "direction_loops", "breakdown", "candidates"):
        png = out / f"{name}.png"
        assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"({name}.png)" in report
    assert "Table V" in report and "stiffness_mismatch" in report


def test_no_effect_is_a_valid_answer(tmp_path, baseline, capsys):
    path = write_log(tmp_path / "clean.csv", synthetic_log(baseline, "none", n=6000))
    out = tmp_path / "r.json"
    assert main(["diagnose", str(path), "--design", DESIGN, "--json", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["present"] == [] and result["ladder"] == []
    assert "No significant unmodelled effect" in capsys.readouterr().out


def _bad(tmp_path, baseline, mutate):
    log = synthetic_log(baseline, "none", n=4000)
    path = write_log(tmp_path / "bad.csv", log)
    text = path.read_text()
    path.write_text(mutate(text))
    return path


@pytest.mark.parametrize("mutate, words", [
    (lambda s: s.replace(",Mz", ""), "missing column(s) Mz"),
    (lambda s: "\n".join(s.splitlines()[:1500]) + "\n", "too few samples"),
    (lambda s: s.replace("\n0.040000,", "\n0.010000,", 1), "not strictly increasing"),
])
def test_bad_logs_exit_2_with_one_line(tmp_path, baseline, capsys, mutate, words):
    path = _bad(tmp_path, baseline, mutate)
    status = main(["diagnose", str(path), "--design", DESIGN, "--quiet"])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and words in err


def test_nan_values_exit_2(tmp_path, baseline, capsys):
    log = synthetic_log(baseline, "none", n=4000)
    log.wrench[100, 2] = np.nan
    path = write_log(tmp_path / "nan.csv", log)
    assert main(["diagnose", str(path), "--design", DESIGN, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "NaN" in err and err.count("\n") == 1


def test_angles_in_degrees_are_caught(tmp_path, baseline, capsys):
    log = synthetic_log(baseline, "none", n=4000)
    log.theta = np.degrees(log.theta)
    path = write_log(tmp_path / "deg.csv", log)
    assert main(["diagnose", str(path), "--design", DESIGN, "--quiet"]) == 2
    assert "degrees" in capsys.readouterr().err


def test_missing_file_and_bad_design(tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "none.csv"), "--design", DESIGN]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["diagnose", str(tmp_path / "none.csv"), "--design",
                 str(tmp_path / "nope.toml")]) == 2


def one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("rows, value", [(slice(100, 110), 1e300), (slice(None), 1e30)])
def test_values_far_outside_the_design_range_are_refused(tmp_path, baseline, capsys, rows,
                                                         value):
    log = synthetic_log(baseline, "none", n=4000)
    log.wrench[rows, 0 if value == 1e300 else 2] = value
    path = write_log(tmp_path / "absurd.csv", log)
    out = tmp_path / "r.json"
    assert main(["diagnose", str(path), "--design", DESIGN, "--json", str(out), "--quiet"]) == 2
    err = one_line(capsys)
    n = 10 if value == 1e300 else 4000
    assert f"{n} samples have a reference wrench far outside the design's range" in err
    assert "up to 3x is accepted" in err and not out.exists()


def test_the_design_named_by_the_log_is_used_and_a_mismatch_refused(tmp_path, baseline, capsys):
    log = synthetic_log(baseline, "none", n=4000)
    path = tmp_path / "d.csv"
    with LogWriter(path, {"design": "delta6", "design_hash": f"0x{baseline.hash32():08x}"}) as w:
        w.write_block(log.t, log.theta, log.wrench)
    stiff = str(DESIGNS / "stiff.toml")
    assert main(["diagnose", str(path), "--design", stiff, "--quiet"]) == 2
    err = one_line(capsys)
    assert f"was recorded with design 'delta6' (hash 0x{baseline.hash32():08x}), but " in err
    assert "stiff.toml has hash" in err and "--force" in err
    # Without --design: the shipped design with the log's hash.
    out = tmp_path / "r.json"
    assert main(["diagnose", str(path), "--json", str(out), "--quiet"]) == 0
    result = json.loads(out.read_text())
    assert result["design"]["hash"] == f"0x{baseline.hash32():08x}" and result["present"] == []
    capsys.readouterr()
    # A hash no shipped design has: the user must name the file.
    text = path.read_text().replace(f"0x{baseline.hash32():08x}", "0x12345678")
    path.write_text(text)
    assert main(["diagnose", str(path), "--quiet"]) == 2
    assert "which is not a shipped design: pass its file with --design" in one_line(capsys)


def test_forcing_a_design_that_differs_from_the_log(tmp_path, baseline, capsys):
    log = synthetic_log(baseline, "none", n=4000)
    path = tmp_path / "d.csv"
    with LogWriter(path, {"design": "delta6", "design_hash": "0x00000001"}) as w:
        w.write_block(log.t, log.theta, log.wrench)
    assert main(["diagnose", str(path), "--design", DESIGN, "--force", "--quiet"]) == 0


def test_a_device_log_is_refused(tmp_path, baseline, capsys):
    """The wrench of a device log is the model's own output: nothing to diagnose."""
    log = synthetic_log(baseline, "none", n=4000)
    for meta in ({"design": "delta6", "wrench_source": "device"},
                 {"design": "delta6", "firmware": "1.0.0", "protocol": "1.0"}):  # older logs
        path = write_log_meta(tmp_path / "dev.csv", log, meta)
        assert main(["diagnose", str(path), "--design", DESIGN, "--quiet"]) == 2
        assert "the device's own model output (a device log), not a reference sensor's" in \
            one_line(capsys)


def write_log_meta(path, log, meta):
    with LogWriter(path, meta) as w:
        w.write_block(log.t, log.theta, log.wrench)
    return path


def test_output_paths_are_checked_before_the_run(tmp_path, stiff_log, capsys):
    existing = tmp_path / "report.md"
    existing.write_text("not a folder")
    assert main(["diagnose", str(stiff_log), "--design", DESIGN, "--report",
                 str(existing)]) == 2
    assert "--report" in one_line(capsys) and existing.read_text() == "not a folder"
    assert main(["diagnose", str(stiff_log), "--design", DESIGN, "--json", str(tmp_path)]) == 2
    assert "is a folder; give a file name" in one_line(capsys)
    assert main(["diagnose", str(stiff_log), "--design", DESIGN, "--json",
                 str(tmp_path / "missing" / "r.json")]) == 2
    assert "does not exist" in one_line(capsys)


def test_json_never_holds_nan():
    from delta6.commands.diagnose import json_safe, summary
    result = {"samples": 5, "seconds": 1.0, "baseline_heldout_p99_pct": [float("nan")] * 6,
              "ladder": [], "present": [], "warnings": ["x"],
              "candidates": [{"name": "a", "score": float("inf")}],
              "groups": [], "partial": [], "implausible": {}, "signature_tests": {},
              "unexplained": {"verdict": {"structured": False}}, "excitation": {"unsupported": []}}
    safe = json_safe(result)
    text = json.dumps(safe, allow_nan=False)
    assert "NaN" not in text and safe["baseline_heldout_p99_pct"] == [None] * 6
    lines = summary(safe).splitlines()
    assert lines[2].split()[-1] == "-" and "a -" in lines[-2] and lines[-1] == "Warning: x"


def test_unphysical_fitted_parameters_are_flagged():
    from delta6.diagnosis.physics import warnings
    assert warnings("joint_friction", {"coulomb_equiv_nm": [0.01] * 6,
                                       "viscous_equiv_nm_s_per_rad": [0.1, -0.02, 0, 0, 0, 0],
                                       "torque_at_ref_speed_nm": [-1] * 6}) == [
        "joint_friction: viscous_equiv_nm_s_per_rad fitted negative (j2 -0.02): not physical; "
        "there the term trades with a neighbouring family or stands in for something else"]
    assert warnings("link_compliance", {"axial_b1_um_per_n": -0.5, "tilt_rad_per_nm": -1.0}) \
        == ["link_compliance: axial_b1_um_per_n fitted negative (-0.5): not physical; the term "
            "stands in for something else"]
    assert warnings("encoder_offset", {"offset_j1_rad": -0.01}) == []


def test_a_negative_viscous_term_on_every_joint_says_how_late_a_reference_would_be():
    """A reference 10 ms late looks like viscous = -k x 10 ms on every joint (an outside
    review's simulator: the diagnosis named friction with that warning and no word of a lag)."""
    from delta6.diagnosis.physics import warnings
    k = [0.64, 0.64, 0.64, 0.96, 0.96, 0.96]
    lagging = {"viscous_equiv_nm_s_per_rad": [-ki * 0.0093 for ki in k]}
    (line,) = warnings("joint_friction", lagging, k)
    assert "about 9 ms late" in line and "fits the rig's latency apart" in line
    # Not without the rates, not on some joints only, not when the joints disagree.
    assert "late" not in warnings("joint_friction", lagging)[0]
    some = {"viscous_equiv_nm_s_per_rad": [-0.006, -0.006, 0.001, -0.009, -0.009, -0.009]}
    assert "late" not in warnings("joint_friction", some, k)[0]
    mixed = {"viscous_equiv_nm_s_per_rad": [-0.001, -0.006, -0.006, -0.009, -0.009, -0.03]}
    assert "late" not in warnings("joint_friction", mixed, k)[0]
