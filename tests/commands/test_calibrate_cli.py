"""``delta6 calibrate``, ``delta6 evaluate`` and ``delta6 simulate --unit`` as a user runs them."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.cli import main
from delta6.core import calibration as C
from delta6.core import curves
from delta6.core.design import load as load_design
from delta6.core.errors import UserError
from delta6.link.logfile import read_log

from conftest import DESIGNS

DESIGN = str(DESIGNS / "delta6.toml")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("unit")
    cal_log, check_log = d / "cal.csv", d / "check.csv"
    assert main(["simulate", "--effect", "stiffness_mismatch", "--effect", "encoder_offset",
                 "--seed", "3", "--duration", "100", "-o", str(cal_log)]) == 0
    assert main(["simulate", "--unit", str(d / "cal.truth.json"), "--seed", "4",
                 "--duration", "60", "-o", str(check_log)]) == 0
    return d, cal_log, check_log


def test_unit_is_the_same_unit_on_a_new_run(runs):
    d, cal_log, check_log = runs
    a = json.loads((d / "cal.truth.json").read_text())
    b = json.loads((d / "check.truth.json").read_text())
    assert a["effects"] == b["effects"] and a["design"] == b["design"]
    assert b["seed"] == 4 and b["duration_s"] == 60
    assert not np.allclose(read_log(cal_log).theta[:100], read_log(check_log).theta[:100])


def test_calibrate_then_evaluate(runs, tmp_path, capsys):
    _, cal_log, check_log = runs
    out = tmp_path / "unit-3.toml"
    assert main(["calibrate", str(cal_log), "--design", DESIGN, "-o", str(out), "--effect",
                 "stiffness_mismatch", "--effect", "encoder_offset", "--report",
                 str(tmp_path / "rep"), "--quiet"]) == 0
    cal = C.load(out)
    assert cal.name == "unit-3" and cal.effects == ("stiffness_mismatch", "encoder_offset")
    assert set(cal.fit["heldout_after"]) == {"p95_pct", "p99_pct", "max_pct"}
    assert (tmp_path / "rep" / "calibration.md").exists()
    assert (tmp_path / "rep" / "heldout_p99.png").read_bytes()[:4] == b"\x89PNG"
    assert "held-out p99" in capsys.readouterr().out

    js = tmp_path / "t.json"
    assert main(["evaluate", str(check_log), "--design", DESIGN, "--calibration", str(out),
                 "--json", str(js)]) == 0
    result = json.loads(js.read_text())
    assert [r["estimator"] for r in result["rows"]] == ["analytical", "calibrated"]
    for r in result["rows"]:
        assert set(r) == {"estimator", "p95_pct", "p99_pct", "max_pct"}
        assert all(len(r[k]) == 6 for k in ("p95_pct", "p99_pct", "max_pct"))
    assert result["samples"] == 3000 and len(result["full_scale"]) == 6
    analytical, calibrated = result["rows"]
    assert max(calibrated["p99_pct"]) < 0.5 * min(analytical["p99_pct"])
    assert "calibrated" in capsys.readouterr().out


def test_evaluate_scores_against_the_reference_advanced_by_the_rig_latency(runs, tmp_path,
                                                                          capsys):
    _, cal_log, check_log = runs
    out = tmp_path / "unit.toml"
    assert main(["calibrate", str(cal_log), "--design", DESIGN, "-o", str(out), "--effect",
                 "stiffness_mismatch", "--rig-latency", "0.02", "--quiet"]) == 0
    cal = C.load(out)
    assert cal.fit["rig_latency_s"] == 0.02 and cal.fit["rig_latency"] == "given"
    assert "20.0 ms (as stated)" in capsys.readouterr().out
    results = {}
    for option in (None, "0", "0.02", "calibration"):
        js = tmp_path / f"{option}.json"
        argv = ["evaluate", str(check_log), "--design", DESIGN, "--calibration", str(out),
                "--json", str(js)] + ([] if option is None else ["--rig-latency", option])
        assert main(argv) == 0
        results[option] = json.loads(js.read_text())
    assert results[None]["rig_latency_s"] == 0.0 and results[None]["samples"] == 3000
    assert results["0"] == results[None]
    assert results["calibration"] == results["0.02"]
    advanced = results["0.02"]
    # 60 s at 50 Hz: the last sample has no reference 20 ms later.
    assert advanced["rig_latency_s"] == 0.02 and advanced["samples"] == 2999
    # This rig has no delay: advancing its reference makes every row worse.
    for before, after in zip(results[None]["rows"], advanced["rows"]):
        assert before["estimator"] == after["estimator"]
        assert np.mean(after["p95_pct"]) > np.mean(before["p95_pct"])
    assert "reference advanced by the rig latency, 20.0 ms" in capsys.readouterr().out


def test_the_advanced_reference_is_the_reference_later_by_the_latency():
    from types import SimpleNamespace

    from delta6.evaluation.tablev import advanced_reference
    t = np.arange(0.0, 1.0, 0.02)
    wrench = np.stack([np.sin(3 * t + i) for i in range(6)], axis=1)
    ref, keep = advanced_reference(SimpleNamespace(t=t, wrench=wrench), 0.03)
    assert keep.sum() == len(t) - 2
    exact = np.stack([np.sin(3 * (t[keep] + 0.03) + i) for i in range(6)], axis=1)
    # Linear interpolation between samples 20 ms apart: within (3 * 0.01)^2 / 2 of the curve.
    np.testing.assert_allclose(ref, exact, atol=(3 * 0.01) ** 2 / 2)


@pytest.mark.parametrize("value,message", [
    ("-0.01", "0..0.2 s"), ("nan", "0..0.2 s"), ("0.5", "0..0.2 s"),
    ("soon", "a number of seconds"), ("calibration", "needs --calibration"),
])
def test_evaluate_refuses_a_bad_rig_latency(runs, capsys, value, message):
    _, _, check_log = runs
    assert main(["evaluate", str(check_log), "--design", DESIGN, "--rig-latency", value]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err


def test_evaluate_refuses_calibration_latency_from_a_file_without_one(runs, tmp_path, capsys,
                                                                     baseline):
    _, _, check_log = runs
    path = C.save(C.neutral(baseline, "old"), tmp_path / "old.toml")
    assert main(["evaluate", str(check_log), "--design", DESIGN, "--calibration", str(path),
                 "--rig-latency", "calibration"]) == 2
    assert "records no rig latency" in capsys.readouterr().err
    # A value out of range (a hand edit, or a bound reached only to within rounding) is named
    # with the file and the field, not as if the user had typed it.
    bad = C.save(C.neutral(baseline, "bad").with_(fit={"rig_latency_s": -1e-18}),
                 tmp_path / "bad.toml")
    assert main(["evaluate", str(check_log), "--design", DESIGN, "--calibration", str(bad),
                 "--rig-latency", "calibration"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{bad}: fit.rig_latency_s:" in err and len(err.splitlines()) == 1, err


def test_evaluate_without_calibration_has_the_analytical_row(runs, capsys):
    _, _, check_log = runs
    assert main(["evaluate", str(check_log), "--design", DESIGN]) == 0
    assert "analytical  p99" in capsys.readouterr().out


@pytest.mark.parametrize("argv,message", [
    (["calibrate", "{log}", "-o", "{tmp}/c.toml", "--effect", "thermal_drift"], "thermal"),
    (["calibrate", "{log}", "-o", "{tmp}/c.toml", "--effect", "warp"], "unknown effect"),
    (["calibrate", "{tmp}/missing.csv", "-o", "{tmp}/c.toml"], "missing.csv"),
    (["calibrate", "{log}", "-o", "{tmp}/nodir/c.toml"], "does not exist"),
    (["calibrate", "{log}", "-o", "{tmp}/c.toml", "--rig-latency", "-1"], "0..0.2 s"),
    (["calibrate", "{log}", "-o", "{tmp}/c.toml", "--rig-latency", "x"], "number of seconds"),
    (["calibrate", "{log}", "-o", "{tmp}/c.toml", "--design", str(DESIGNS / "stiff.toml")],
     "recorded with design"),
    (["evaluate", "{log}", "--calibration", "{tmp}/missing.toml"], "no such file"),
    (["simulate", "--unit", "{tmp}/missing.truth.json", "-o", "{tmp}/x.csv"], "no such file"),
    (["simulate", "--unit", "{truth}", "--effect", "backlash", "-o", "{tmp}/x.csv"],
     "drop --effect"),
])
def test_bad_input_is_one_line_and_status_2(runs, tmp_path, capsys, argv, message):
    d, cal_log, _ = runs
    argv = [a.format(log=cal_log, tmp=tmp_path, truth=d / "cal.truth.json") for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err


def test_a_calibration_for_another_design_is_refused(runs, tmp_path, capsys, baseline):
    _, _, check_log = runs
    other = C.neutral(baseline.replace(lb_mm=121.0), "other")
    path = C.save(other, tmp_path / "other.toml")
    assert main(["evaluate", str(check_log), "--design", DESIGN, "--calibration",
                 str(path)]) == 2
    assert "fitted for design" in capsys.readouterr().err


def test_codegen_writes_and_removes_the_calibration_header(tmp_path, baseline, capsys):
    cal = C.save(C.neutral(baseline, "unit-x").with_(offset_rad=np.full(6, 1e-3)),
                 tmp_path / "unit.toml")
    out = tmp_path / "generated" / "delta6_design.h"
    header = out.with_name("delta6_calibration.h")
    assert main(["codegen", DESIGN, "-o", str(out), "--calibration", str(cal)]) == 0
    text = header.read_text()
    assert "GENERATED FILE" in text and '"unit-x"' in text
    assert f"0x{C.load(cal).hash32():08X}UL" in text
    assert main(["codegen", DESIGN, "-o", str(out), "--calibration", str(cal), "--check"]) == 0
    assert main(["codegen", DESIGN, "-o", str(out), "--check"]) == 1    # it is still there
    assert main(["codegen", DESIGN, "-o", str(out)]) == 0
    assert not header.exists() and "removed" in capsys.readouterr().out
    other = C.save(C.neutral(baseline.replace(lb_mm=121.0), "other"), tmp_path / "o.toml")
    assert main(["codegen", DESIGN, "-o", str(out), "--calibration", str(other)]) == 2


def test_calibrate_checks_its_outputs_and_refuses_a_device_log_before_fitting(tmp_path, capsys):
    from delta6.link.logfile import LogWriter
    log = tmp_path / "device.csv"
    with LogWriter(log, {"design": "delta6", "wrench_source": "device"}) as w:
        w.write_block(np.arange(10) * 0.004, np.zeros((10, 6)), np.zeros((10, 6)))
    cases = [
        (["-o", str(tmp_path / "none" / "c.toml")], "the folder"),
        (["-o", str(tmp_path)], "is a folder; give a file name"),
        (["-o", str(tmp_path / "c.toml"), "--report", str(log)], "exists and is not a folder"),
        (["-o", str(tmp_path / "c.toml")], "the device's own model output (a device log)"),
    ]
    for options, words in cases:
        assert main(["calibrate", str(log), "--design", DESIGN, "--quiet", *options]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
    assert main(["evaluate", str(log), "--design", DESIGN, "--json", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_a_curve_is_calibrated_and_compiled_from_the_command_line(tmp_path, capsys):
    """`--effect nonlinear_spring` fits the spring's curve and the rate that carries its
    straight part; evaluate scores it, codegen writes its tables into the header."""
    log, check = tmp_path / "spring.csv", tmp_path / "spring-check.csv"
    assert main(["simulate", "--effect", "nonlinear_spring", "--magnitude", "1", "--seed", "6",
                 "--duration", "60", "-o", str(log)]) == 0
    assert main(["simulate", "--unit", str(tmp_path / "spring.truth.json"), "--seed", "7",
                 "--duration", "40", "-o", str(check)]) == 0
    out = tmp_path / "spring-unit.toml"
    assert main(["calibrate", str(log), "--design", DESIGN, "-o", str(out), "--effect",
                 "nonlinear_spring", "--quiet"]) == 0
    cal = C.load(out)
    assert cal.effects == ("nonlinear_spring", "stiffness_mismatch") and curves.has_curves(load_design(DESIGN), cal)
    js = tmp_path / "t.json"
    assert main(["evaluate", str(check), "--design", DESIGN, "--calibration", str(out),
                 "--json", str(js)]) == 0
    analytical, calibrated = json.loads(js.read_text())["rows"]
    assert max(calibrated["p99_pct"]) < 0.3 * max(analytical["p99_pct"])
    header = tmp_path / "generated" / "delta6_design.h"
    assert main(["codegen", DESIGN, "-o", str(header), "--calibration", str(out)]) == 0
    text = header.with_name("delta6_calibration.h").read_text()
    assert "kCurveTorque6" in text and "kCurveAngle1" not in text


def test_a_joint_that_never_moves_is_refused_and_a_frozen_stretch_noted(runs, tmp_path, capsys):
    """A stuck encoder gave an identity calibration, 'nothing significant', exit 0; a frozen
    stretch calibrated several times worse, silently."""
    from delta6.link.logfile import LogWriter
    _, cal_log, _ = runs
    log = read_log(cal_log)
    stuck, frozen = tmp_path / "stuck.csv", tmp_path / "frozen.csv"
    for path, cols, rows in ((stuck, [2], slice(None)),
                             (frozen, [1], (log.t >= 20) & (log.t < 45))):
        theta = log.theta.copy()
        theta[rows, cols[0]] = theta[np.argmax(rows) if not isinstance(rows, slice) else 0,
                                     cols[0]]
        with LogWriter(path, dict(log.meta)) as w:
            w.write_block(log.t, theta, log.wrench)
    out = tmp_path / "s.toml"
    assert main(["calibrate", str(stuck), "--design", DESIGN, "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "theta_e3 hardly moves" in err[0] and not out.exists()
    assert main(["calibrate", str(frozen), "--design", DESIGN, "-o", str(out), "--quiet",
                 "--effect", "stiffness_mismatch"]) == 0
    assert "theta_e2 stands exactly still for 25 s from t = 20" in capsys.readouterr().err


def test_latency_named_as_an_effect_is_refused_with_the_reason(runs, tmp_path, capsys):
    _, cal_log, _ = runs
    assert main(["calibrate", str(cal_log), "--design", DESIGN, "-o", str(tmp_path / "x.toml"),
                 "--effect", "sensor_latency"]) == 2
    assert "always fitted, never corrected on the board" in capsys.readouterr().err


def test_every_kth_sample_fits_the_log_at_a_lower_rate(runs, tmp_path, capsys):
    """--every K: a long or fast log in 1/K of the memory; the same unit's effects found."""
    _, cal_log, check_log = runs
    out = tmp_path / "thin.toml"
    assert main(["calibrate", str(cal_log), "--design", DESIGN, "-o", str(out), "--effect",
                 "stiffness_mismatch", "--effect", "encoder_offset", "--every", "2",
                 "--quiet"]) == 0
    cal = C.load(out)
    assert cal.fit["samples"] == (len(read_log(cal_log)) + 1) // 2
    assert cal.fit["rate_hz"] == pytest.approx(25.0, rel=1e-6)
    full = tmp_path / "full.toml"
    assert main(["calibrate", str(cal_log), "--design", DESIGN, "-o", str(full), "--effect",
                 "stiffness_mismatch", "--effect", "encoder_offset", "--quiet"]) == 0
    np.testing.assert_allclose(cal.rate_ratio, C.load(full).rate_ratio, atol=3e-3)
    np.testing.assert_allclose(cal.offset_rad, C.load(full).offset_rad, atol=3e-4)
    capsys.readouterr()
    with pytest.raises(SystemExit) as info:      # argparse's usage error
        main(["calibrate", str(cal_log), "-o", str(tmp_path / "x.toml"), "--every", "0"])
    assert info.value.code == 2 and "--every must be at least 1" in capsys.readouterr().err


def test_a_fit_the_memory_cannot_hold_is_refused_before_the_work():
    from delta6.commands.calibrate import check_memory, fit_memory
    check_memory(100_000, 1, available=fit_memory(100_000))                # fits: nothing
    check_memory(100_000, 1, available=None)                              # unknown: nothing
    with pytest.raises(Exception) as info:
        check_memory(400_000, 2, available=fit_memory(100_000))
    message = str(info.value)
    assert "400000 samples" in message and "--every 8" in message and "\n" not in message
    # The --every it names fits: the log read at 1/8 of its rate, 50,000 samples.
    check_memory(50_000, 1, available=fit_memory(100_000))
    with pytest.raises(Exception) as info:
        check_memory(100_000, 1, available=fit_memory(0))                 # no room at all
    assert "too little for any fit" in str(info.value)


@given(samples=st.integers(2_000, 10**7), every=st.integers(1, 8),
       available=st.integers(10**8, 64 * 10**9))
def test_the_every_a_refusal_names_fits_in_the_memory(samples, every, available):
    from delta6.commands.calibrate import check_memory, fit_memory
    try:
        check_memory(samples, every, available=available)
    except UserError as exc:
        text = str(exc)
        if "--every" not in text:
            assert "too little for any fit" in text
            return
        k = int(text.split("--every ")[1].split()[0])
        assert k % every == 0 and k > every
        assert fit_memory(-(-samples // (k // every))) <= available
        assert fit_memory(-(-samples // (k // every - 1))) > available     # the least
    else:
        assert fit_memory(samples) <= available


def test_a_log_too_short_after_every_says_so(runs, tmp_path, capsys):
    _, cal_log, _ = runs
    assert main(["calibrate", str(cal_log), "-o", str(tmp_path / "x.toml"), "--every",
                 "100"]) == 2
    err = capsys.readouterr().err.strip()
    assert "after --every 100" in err and "too few samples" in err and "\n" not in err


def test_evaluate_notes_joints_faster_than_the_calibration_run(runs, tmp_path, capsys,
                                                             baseline):
    """A calibration's friction is known up to the speeds its run reached: evaluating a run
    whose joint went well beyond says so, per joint, and still gives the table."""
    _, _, check_log = runs
    limit = np.full(6, 50.0)
    limit[1] = 0.01
    for limits, expected in ((limit, ["joint 2 turned faster than the 0.01 rad/s"]),
                             (np.full(6, 50.0), [])):
        path = tmp_path / "fast.toml"
        C.save(C.neutral(baseline, "held").with_(effects=("joint_friction",),
                                                 friction_speed_limit_rad_s=limits), path)
        assert main(["evaluate", str(check_log), "--design", DESIGN, "--calibration",
                     str(path)]) == 0
        captured = capsys.readouterr()
        notes = [ln for ln in captured.err.splitlines() if "its calibration run reached" in ln]
        assert [n[len("note: "):][:len(e)] for n, e in zip(notes, expected)] == expected
        assert len(notes) == len(expected) and "calibrated" in captured.out
