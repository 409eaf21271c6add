"""The verdict lines of the report and of the command's summary name the harness's clamp when
a second pass fitted the hinge there, and say nothing of it otherwise."""
from delta6.diagnosis.report import verdict_lines


def _result(clamp):
    return {"groups": [], "partial": [], "implausible": {}, "signature_tests": {},
            "unexplained": {"verdict": {"structured": False}},
            "excitation": {"unsupported": []}, "harness_clamp_mm": clamp}


def test_the_clamp_of_a_second_pass_is_reported():
    lines = verdict_lines(_result([24.6, -3.4, 0.0]))
    (line,) = [x for x in lines if "clamped" in x]
    assert "+24.6, -3.4, +0.0 mm" in line


def test_no_clamp_line_without_a_second_pass():
    assert not any("clamped" in x for x in verdict_lines(_result(None)))


def test_the_cable_of_a_second_pass_is_reported():
    result = _result(None)
    result["harness_cable"] = {"direction": [-0.32, -0.27, -0.91], "slack_mm": 2.0}
    (line,) = [x for x in verdict_lines(result) if "one cable" in x]
    assert "-0.32, -0.27, -0.91" in line and "slack of 2 mm" in line
    assert not any("one cable" in x for x in verdict_lines(_result(None)))
