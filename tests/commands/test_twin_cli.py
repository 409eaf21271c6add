"""``delta6 simulate``: the happy paths, the summary, and one-line errors with exit status 2."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from delta6.cli import main
from delta6.link.logfile import read_log

from conftest import ROOT


def simulate(tmp_path, *args):
    return main(["simulate", "--duration", "10", "-o", str(tmp_path / "run.csv"), *args])


def test_scenario_run_writes_log_truth_and_summary(tmp_path, capsys):
    assert simulate(tmp_path, "--scenario", "paper", "--seed", "3") == 0
    out = capsys.readouterr().out
    assert "run.truth.json" in out and "p99 % FS" in out and "backlash (dead_zone" in out
    log = read_log(tmp_path / "run.csv")
    truth = json.loads((tmp_path / "run.truth.json").read_text())
    assert len(log) == 500 and truth["seed"] == 3 and truth["scenario"] == "paper"
    assert not list(tmp_path.glob("*.partial"))


def test_effects_from_the_command_line(tmp_path, capsys):
    assert simulate(tmp_path, "--effect", "backlash", "--effect",
                    "joint_friction:coulomb_nm=0.01,formulation=lugre", "--magnitude", "0.7",
                    "--effect", "stiffness_mismatch:deviation=0.05,joints=4") == 0
    truth = json.loads((tmp_path / "run.truth.json").read_text())
    by_name = {e["name"]: e for e in truth["effects"]}
    assert by_name["backlash"]["magnitude"] == 0.7
    friction = by_name["joint_friction"]
    assert friction["formulation"] == "lugre" and friction["parameters"]["coulomb_nm"] == [0.01] * 6
    assert by_name["stiffness_mismatch"]["parameters"]["deviation"] == [0, 0, 0, 0.05, 0, 0]
    assert truth["scenario"] is None


def test_random_draws_are_recorded(tmp_path, capsys):
    assert simulate(tmp_path, "--random", "--effect", "spring_hysteresis", "--effect",
                    "joint_friction", "--seed", "123", "--record-temp") == 0
    truth = json.loads((tmp_path / "run.truth.json").read_text())
    for e in truth["effects"]:
        assert 0 <= e["magnitude"] <= 1 and e["formulation"]
    assert truth["temperature"]["recorded"] and read_log(tmp_path / "run.csv").temp_c is not None


def test_list_needs_no_output(capsys):
    assert main(["simulate", "--list"]) == 0
    out = capsys.readouterr().out
    assert "spring_hysteresis" in out and "play_sum" in out and "paper" in out


@pytest.mark.parametrize("args,message", [
    (["--scenario", "perfect"], "unknown scenario 'perfect'"),
    (["--effect", "gravity"], "unknown effect 'gravity'"),
    (["--effect", "backlash:slack=1"], "unknown parameter 'slack'"),
    (["--effect", "backlash:play_rad=wide"], "play_rad takes numbers"),
    (["--effect", "backlash:play_rad"], "expected key=value"),
    (["--effect", "backlash:play_rad=-0.1"], "must lie in"),
    (["--effect", "backlash:formulation=gear"], "unknown formulation 'gear'"),
    (["--effect", "backlash", "--effect", "backlash"], "requested twice"),
    (["--magnitude", "1.5", "--effect", "backlash"], "--magnitude must be in [0, 1]"),
    (["--scenario", "paper", "--magnitude", "0.3"], "parameters are fixed"),
    (["--seed", "-3"], "--seed must be >= 0"),
    (["--seed", "x"], "--seed takes a whole number"),
    (["--duration", "0"], "fewer than 2 samples"),
    (["--rate", "nan"], "--rate must be"),
    (["--duration", "inf"], "--duration must be a finite number, got inf"),
    # A slower log's sample step reads as milliseconds to every reader: not written at all.
    (["--rate", "0.7"], "--rate must be at least 1 Hz"),
    (["--random"], "give at least one --effect"),
    (["--design", "nowhere.toml"], "no such file"),
])
def test_bad_arguments_get_one_line_and_status_2(tmp_path, capsys, args, message):
    assert simulate(tmp_path, *args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("delta6 simulate: error:")
    assert message in err[0]
    assert not (tmp_path / "run.csv").exists()


def test_an_existing_log_or_truth_is_replaced_only_with_force(tmp_path, capsys):
    # A rig log of that name is not regenerable: refused before any work, as delta6 log does.
    log, truth = tmp_path / "run.csv", tmp_path / "run.truth.json"
    log.write_text("a rig's recording\n")
    assert simulate(tmp_path) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"-o {log} exists" in err and "--force" in err, err
    assert log.read_text() == "a rig's recording\n" and not truth.exists()
    log.unlink()
    truth.write_text("{}")
    assert simulate(tmp_path) == 2
    assert f"-o {truth} exists" in capsys.readouterr().err
    assert not log.exists() and truth.read_text() == "{}"
    assert simulate(tmp_path, "--force") == 0
    assert len(read_log(log)) == 500 and json.loads(truth.read_text())["samples"] == 500


def test_missing_output_and_bad_directory(tmp_path, capsys):
    assert main(["simulate", "--duration", "5"]) == 2
    assert "missing -o" in capsys.readouterr().err
    assert main(["simulate", "--duration", "5", "-o", str(tmp_path / "no" / "x.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_command_runs_as_a_program(tmp_path):
    out = subprocess.run([sys.executable, "-m", "delta6", "simulate", "--scenario", "nope",
                          "-o", str(tmp_path / "a.csv")], capture_output=True, text=True,
                         cwd=ROOT)
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    ok = subprocess.run([sys.executable, "-m", "delta6", "simulate", "--scenario",
                         "joint_friction", "--duration", "4", "-o", str(tmp_path / "b.csv")],
                        capture_output=True, text=True, cwd=ROOT)
    assert ok.returncode == 0, ok.stderr
    assert np.isfinite(read_log(tmp_path / "b.csv").wrench).all()


def test_a_damaged_truth_file_for_unit_gets_one_line(tmp_path, capsys):
    # A hand-edited truth file: every field the unit needs, removed or given the wrong type.
    assert simulate(tmp_path, "--scenario", "paper") == 0
    truth = json.loads((tmp_path / "run.truth.json").read_text())
    needed = ("seed", "duration_s", "rate_hz", "trajectory", "temperature", "measurement",
              "oversample", "scenario", "effects", "design")
    damaged = [{k: v for k, v in truth.items() if k != key} for key in needed]
    damaged += [{**truth, key: 5} for key in ("trajectory", "temperature", "effects", "design")]
    for i, record in enumerate(damaged):
        path = tmp_path / f"bad{i}.truth.json"
        path.write_text(json.dumps(record))
        capsys.readouterr()
        assert main(["simulate", "--unit", str(path), "--duration", "2",
                     "-o", str(tmp_path / "again.csv")]) == 2, sorted(set(truth) - set(record))
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and path.name in err, err


def test_a_reference_beyond_what_the_readers_accept_is_noted(tmp_path, capsys):
    # Friction in N*m does not scale with the springs: on springs 300 times softer than the
    # paper's the same effects outgrow the design's full scale, and evaluate, diagnose,
    # calibrate and train would refuse the log; simulate says so when it writes it.
    text = (ROOT / "designs" / "delta6.toml").read_text()
    soft = tmp_path / "soft.toml"
    soft.write_text(text.replace('name = "delta6"', 'name = "soft"').replace(
        "k_nm_per_rad = 0.639236", "k_nm_per_rad = 0.002"))
    assert simulate(tmp_path, "--scenario", "paper", "--design", str(soft)) == 0
    out = capsys.readouterr().out
    assert "beyond 3x the design's full scale" in out
    assert main(["evaluate", str(tmp_path / "run.csv"), "--design", str(soft)]) == 2
    assert "far outside the design's range" in capsys.readouterr().err
    # The shipped design's run has no such note.
    assert simulate(tmp_path, "--scenario", "paper", "-o", str(tmp_path / "ok.csv")) == 0
    assert "full scale (most on" not in capsys.readouterr().out
