"""What `delta6 calibrate` says it corrects, and why: the diagnosis's verdict apart from the
families the calibration added, and a note when a hysteresis family's loops run backwards."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from delta6.calibration.fit import _anti_dissipative
from delta6.calibration.report import corrected
from delta6.core.calibration import neutral
from delta6.core.design import load

from conftest import DESIGNS

DESIGN = load(DESIGNS / "delta6.toml")


def fit_of(effects, diagnosis, chosen_by="diagnosis"):
    return SimpleNamespace(calibration=neutral(DESIGN).with_(effects=tuple(effects)),
                           diagnosis=diagnosis, chosen_by=chosen_by)


def test_added_families_are_told_apart_from_the_verdict():
    verdict = {"present": ["joint_friction", "backlash"], "groups": [], "straight_part": []}
    text = corrected(fit_of(["joint_friction", "backlash", "geometry_error"], verdict))
    assert text == ("joint_friction, backlash (the diagnosis's verdict); geometry_error "
                    "(added: each lowered the held-out error further)")
    assert corrected(fit_of(["geometry_error"], {"present": ["sensor_latency"], "groups": []})) \
        == "geometry_error (added: each lowered the held-out error further)"
    assert corrected(fit_of(["backlash"], None, "--effect")) == "backlash (chosen by --effect)"
    assert corrected(fit_of([], verdict)).startswith("nothing")


def test_backwards_loops_are_noted():
    cal = neutral(DESIGN).with_(effects=("spring_hysteresis",))
    weights = np.full_like(cal.hysteresis_nm, -1e-3)
    weights[0] = 1e-3
    note = _anti_dissipative(cal.with_(hysteresis_nm=weights))
    assert len(note) == 1 and "joints 2, 3, 4, 5, 6" in note[0]
    assert _anti_dissipative(cal.with_(hysteresis_nm=-weights)) == []
    assert _anti_dissipative(neutral(DESIGN).with_(hysteresis_nm=weights)) == []


def test_a_family_left_out_for_a_format_limit_is_not_called_implausible():
    from delta6.calibration.fit import _why_out

    def check(quantity):
        return {"quantity": quantity, "largest": 2.0, "limit": 1.0, "ratio": 2.0}

    assert _why_out([check("board_table_torque_nm")]) == \
        "it needs more than the board's curve tables hold"
    assert "file's bounds" in _why_out([check("file_bounds (field 'x': too big)")])
    assert "plausible" in _why_out([check("loop_half_width_nm")])
    assert "plausible" in _why_out([check("board_table_torque_nm"), check("angle_error_rad")])
