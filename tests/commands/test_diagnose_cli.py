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
