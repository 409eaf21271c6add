"""``delta6 simulate --unit``: a hand-edited truth file is checked as ``--effect`` and the
settings' own checks check the command line: one line naming the file and the field, exit 2,
no output; a legal edit gives a run whose outputs are all finite."""
from __future__ import annotations

import copy
import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from delta6.cli import main
from delta6.link.logfile import read_log


@pytest.fixture(scope="module")
def truth(tmp_path_factory) -> dict:
    """A real truth file with every section, and effects of each parameter shape."""
    folder = tmp_path_factory.mktemp("unit")
    assert main(["simulate", "--scenario", "paper", "--effect", "thermal_drift:formulation=lagged",
                 "--effect", "harness", "--effect", "nonlinear_spring", "--duration", "4",
                 "--seed", "1", "-o", str(folder / "cal.csv")]) == 0
    return json.loads((folder / "cal.truth.json").read_text())


def _strict(text: str):
    """JSON as the standard has it: NaN and Infinity are no JSON."""
    def refuse(token):
        raise ValueError(f"{token} in the truth file")
    return json.loads(text, parse_constant=refuse)


def _run_unit(record: dict, folder: Path, capsys) -> tuple[int, str, str]:
    bad = folder / "bad.truth.json"
    bad.write_text(json.dumps(record))
    capsys.readouterr()
    status = main(["simulate", "--unit", str(bad), "--duration", "2", "--seed", "3",
                   "-o", str(folder / "out.csv")])
    out, err = capsys.readouterr()
    return status, out, err


def _refused(status, err, folder, *words):
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, err
    assert lines[0].startswith("delta6 simulate: error: ") and "bad.truth.json" in lines[0]
    for w in words:
        assert w in lines[0], lines[0]
    assert not (folder / "out.csv").exists() and not (folder / "out.truth.json").exists()


def _effect(record, name):
    return next(e for e in record["effects"] if e["name"] == name)


# The reviewers' reproducers, and a field of each section.
CASES = {
    "deviation NaN": (lambda t: _effect(t, "stiffness_mismatch")["parameters"]["deviation"]
                      .__setitem__(0, math.nan), ["stiffness_mismatch", "deviation", "finite"]),
    "deviation huge": (lambda t: _effect(t, "stiffness_mismatch")["parameters"]["deviation"]
                       .__setitem__(0, 1e9), ["deviation must lie in [-0.5, 0.5]"]),
    "latency 1e6 s": (lambda t: _effect(t, "sensor_latency")["parameters"]
                      .__setitem__("latency_s", 1e6), ["latency_s must lie in [0, 1] s"]),
    "deviation too short": (lambda t: _effect(t, "stiffness_mismatch")["parameters"]
                            .__setitem__("deviation", [0.1, 0.1]), ["deviation takes one number or 6"]),
    "force noise NaN": (lambda t: t["measurement"]["reference_noise"]
                        .__setitem__("force_sd_n", math.nan),
                        ["measurement.reference_noise.force_sd_n: must be finite"]),
    "moment noise negative": (lambda t: t["measurement"]["reference_noise"]
                              .__setitem__("moment_sd_nm", -1.0),
                              ["measurement.reference_noise.moment_sd_nm: must be >= 0"]),
    "encoder bits": (lambda t: t["measurement"].__setitem__("encoder_bits", 30),
                     ["measurement.encoder_bits"]),
    "sensor offset length": (lambda t: t["measurement"]["sensor_frame"]
                             .__setitem__("p_t_m", [0.0, 0.0]),
                             ["measurement.sensor_frame.p_t_m: takes 3 numbers"]),
    "speed NaN": (lambda t: t["trajectory"].__setitem__("speed_max_rad_s", math.nan),
                  ["trajectory.speed_max_rad_s: must be finite"]),
    "move_max below move_min": (lambda t: t["trajectory"].__setitem__("move_max_s", 0.5),
                                ["trajectory.move_max_s", "move_min_s"]),
    "temperature steps": (lambda t: t["temperature"].__setitem__("steps", 0),
                          ["temperature.steps"]),
    "high below low": (lambda t: t["temperature"].__setitem__("high_c", -300.0),
                       ["temperature.high_c"]),
    "oversample": (lambda t: t.__setitem__("oversample", 0), ["oversample"]),
    "magnitude NaN": (lambda t: _effect(t, "harness").__setitem__("magnitude", math.nan),
                      ["harness: magnitude"]),
    "design length": (lambda t: t["design"]["parameters"].__setitem__("a_mm", math.inf),
                      ["design", "a_mm"]),
    "an effect twice": (lambda t: t["effects"].append(t["effects"][0]), ["recorded twice"]),
    "unknown formulation": (lambda t: _effect(t, "backlash").__setitem__("formulation", "gear"),
                            ["backlash: unknown formulation 'gear'"]),
    "unknown trajectory field": (lambda t: t["trajectory"].__setitem__("jerk", 1.0),
                                 ["trajectory.jerk: unknown field"]),
    "parameter as text": (lambda t: _effect(t, "backlash")["parameters"]
                          .__setitem__("play_rad", "wide"), ["play_rad takes numbers"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_bad_value_in_the_unit_file_is_one_line_naming_it(truth, case, tmp_path, capsys):
    record = copy.deepcopy(truth)
    edit, words = CASES[case]
    edit(record)
    status, _, err = _run_unit(record, tmp_path, capsys)
    _refused(status, err, tmp_path, *words)


def test_the_same_values_are_refused_on_the_command_line_too(tmp_path, capsys):
    for spec in ("stiffness_mismatch:deviation=1e9", "sensor_latency:latency_s=1e6"):
        assert main(["simulate", "--effect", spec, "--duration", "2",
                     "-o", str(tmp_path / "x.csv")]) == 2
        assert "must lie in" in capsys.readouterr().err


def _numeric_leaves(value, path=()):
    """Paths to every number of a JSON document (not the booleans)."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _numeric_leaves(v, path + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _numeric_leaves(v, path + (i,))
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield path


def _corrupt(record: dict, path, how: str) -> None:
    parent = record
    for key in path[:-1]:
        parent = parent[key]
    old = parent[path[-1]]
    if how == "wrong length" and isinstance(parent, list):
        parent.append(parent[-1])            # one element too many
        return
    parent[path[-1]] = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf, "huge": 1e9,
                        "-huge": -1e9, "negative": -abs(old) - 1.0, "zero": 0,
                        "wrong length": [old, old]}[how]


# capsys is emptied before each run
@settings(max_examples=40, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(),
       how=st.sampled_from(["nan", "inf", "-inf", "huge", "-huge", "negative", "zero",
                            "wrong length"]))
def test_a_corrupted_number_is_refused_or_runs_finite(truth, capsys, data, how):
    leaves = sorted(_numeric_leaves(truth), key=str)
    path = data.draw(st.sampled_from(leaves), label="field")
    record = copy.deepcopy(truth)
    _corrupt(record, path, how)
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        status, out, err = _run_unit(record, folder, capsys)
        if status != 0:
            _refused(status, err, folder)
            return
        # A legal value (or a field the run does not read): everything it wrote is finite.
        log = read_log(folder / "out.csv")
        assert np.isfinite(log.theta).all() and np.isfinite(log.wrench).all(), path
        written = _strict((folder / "out.truth.json").read_text())
        assert written["samples"] == len(log) == 100
        assert "nan" not in out.lower() and "inf" not in out.lower(), out
