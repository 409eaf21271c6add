"""The verdict lines of the report and of the command's summary name the harness's clamp when
a second pass fitted the hinge there and the harness is named, and say nothing of it
otherwise."""
from delta6.diagnosis.report import verdict_lines


def _result(clamp, present=("harness",)):
    return {"present": list(present), "groups": [], "partial": [], "implausible": {},
            "signature_tests": {}, "unexplained": {"verdict": {"structured": False}},
            "excitation": {"unsupported": []}, "harness_clamp_mm": clamp}


def test_the_clamp_of_a_second_pass_is_reported():
    lines = verdict_lines(_result([24.6, -3.4, 0.0]))
    (line,) = [x for x in lines if "clamped" in x]
    assert "+24.6, -3.4, +0.0 mm" in line


def test_no_clamp_line_without_a_second_pass():
    assert not any("clamped" in x for x in verdict_lines(_result(None)))


def test_no_clamp_or_cable_line_when_the_harness_is_not_named():
    result = _result([24.6, -3.4, 0.0], present=["stiffness_mismatch"])
    result["harness_cable"] = {"direction": [0.0, 0.0, -1.0], "slack_mm": 2.0}
    result["minor"] = [{"name": "harness", "share_of_gap": 0.01, "share_with_traded": 0.01,
                        "share_alone": 0.01}]
    lines = verdict_lines(result)
    assert not any("clamped" in x or "one cable" in x for x in lines)
    # Named through a group verdict, it is described.
    result["groups"] = [{"members": ["harness", "link_compliance"], "named_alone": [],
                         "share_of_gap": 0.2, "text": "harness and/or link_compliance"}]
    lines = verdict_lines(result)
    assert any("clamped" in x for x in lines) and any("one cable" in x for x in lines)


def test_the_cable_of_a_second_pass_is_reported():
    result = _result(None)
    result["harness_cable"] = {"direction": [-0.32, -0.27, -0.91], "slack_mm": 2.0}
    (line,) = [x for x in verdict_lines(result) if "one cable" in x]
    assert "-0.32, -0.27, -0.91" in line and "slack of 2 mm" in line
    assert not any("one cable" in x for x in verdict_lines(_result(None)))


def test_a_fragment_of_the_leftover_is_told_apart_from_an_absorber():
    result = {**_result(None), "partial": [
        {"name": "joint_friction", "share_of_gap": 0.02, "fragment": True,
         "leftover_share": 0.07},
        {"name": "encoder_offset", "share_of_gap": 0.12, "fragment": False,
         "leftover_share": 0.4}]}
    lines = verdict_lines(result)
    (fragment,) = [x for x in lines if "joint_friction" in x]
    (absorber,) = [x for x in lines if "encoder_offset" in x]
    assert "fragment" in fragment and "7 %" in fragment
    assert "12 %" in absorber and "fragment" not in absorber


def test_a_minor_family_reports_what_it_removes_alone():
    result = {**_result(None), "minor": [
        {"name": "encoder_offset", "share_of_gap": 0.03, "share_with_traded": 0.03,
         "share_alone": 0.012}]}
    (line,) = [x for x in verdict_lines(result) if "encoder_offset" in x]
    assert "3.0 % of the gap" in line and "1.2 % alone" in line
    assert "neighbours" in line and "signature" not in line


def test_a_confirmed_but_small_family_says_its_signature_shows_it():
    result = {**_result(None), "minor": [
        {"name": "backlash", "share_of_gap": 0.006, "share_with_traded": 0.006,
         "share_alone": 0.048, "confirmed": True}]}
    (line,) = [x for x in verdict_lines(result) if "backlash" in x]
    assert "0.6 % of the gap" in line and "4.8 % alone" in line
    assert "signature shows it" in line and "neighbours" not in line


def test_a_named_effect_no_calibration_corrects_says_so():
    # The diagnosis predicted a harness's shrink; delta6 calibrate reports it, never applies it.
    (line,) = [x for x in verdict_lines(_result(None)) if "not corrected" in x]
    assert line.startswith("- harness is not corrected by `delta6 calibrate`")
    grouped = {**_result(None, present=("stiffness_mismatch",)),
               "groups": [{"members": ["thermal_drift", "harness"], "text": "t"}]}
    lines = [x for x in verdict_lines(grouped) if "not corrected" in x]
    assert [x.split()[1] for x in lines] == ["harness", "thermal_drift"]
    assert not [x for x in verdict_lines(_result(None, present=("backlash",)))
                if "not corrected" in x]


def test_a_play_beside_the_hysteresis_is_said_with_its_size_per_joint():
    result = _result(None, present=["spring_hysteresis"])
    group = {"group": "direction-dependent joint torque",
             "members": ["spring_hysteresis", "backlash"], "named_alone": ["spring_hysteresis"],
             "share_of_gap": 0.6,
             "text": "direction-dependent joint torque: spring_hysteresis and/or backlash, "
                     "together 60 % of the gap"}
    result["groups"] = [group]
    assert not any("play fitted" in x for x in verdict_lines(result))
    group["play_beside"] = {"play_rad": [0.0071, 0.0002, 0.0093, 0.0064, 0.0, 0.0],
                            "joints": [1, 3, 4]}
    (line,) = [x for x in verdict_lines(result) if "play fitted" in x]
    assert "7.1 mrad on joint 1, 9.3 mrad on joint 3, 6.4 mrad on joint 4" in line
    assert "spring_hysteresis and/or backlash" in line
