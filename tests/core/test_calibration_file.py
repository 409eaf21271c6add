"""Calibration files: round trip, hash, and one-line errors for bad files (fuzzed)."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.core import calibration as C


def _random_cal(baseline, rng) -> C.Calibration:
    r = rng.uniform
    return C.neutral(baseline, "unit-7").with_(
        effects=("encoder_offset", "joint_friction"),
        offset_rad=r(-0.01, 0.01, 6), backlash_play_rad=r(0, 0.01, 6),
        rate_ratio=r(0.9, 1.1, 6), hysteresis_nm=r(-0.01, 0.01, (6, 3)),
        friction_sign_nm=r(-0.01, 0.01, (6, 2)), viscous_nm_s_per_rad=r(0, 0.01, 6),
        presliding_nm=r(-0.003, 0.003, 6), delta_a_mm=r(-0.5, 0.5, 3),
        delta_lb_mm=r(-0.5, 0.5, 3), delta_azimuth_rad=r(-0.01, 0.01, 3),
        gimbal_misalignment_rad=r(-0.01, 0.01, 3), elbow_rad_per_nm=r(0, 0.2, 3),
        tilt_rad_per_nm=float(r(0, 0.1)), spring_curvature=r(-0.2, 0.2, (6, 2)),
        encoder_periodic_rad=r(-0.004, 0.004, (6, 8)),
        friction_speed_limit_rad_s=r(0.0, 3.0, 6), speed_lead_s=float(r(0.0, 0.05)),
        fit={"log": "cal.csv", "samples": 100, "heldout_before": {"p99_pct": [1.0] * 6}})


@given(st.integers(0, 2**32 - 1))
def test_round_trip_is_exact(baseline, seed):
    cal = _random_cal(baseline, np.random.default_rng(seed))
    back = C.loads(C.dumps(cal))
    assert back.hash32() == cal.hash32()
    for name in ("offset_rad", "hysteresis_nm", "friction_sign_nm", "delta_lb_mm",
                 "spring_curvature", "encoder_periodic_rad", "friction_speed_limit_rad_s"):
        np.testing.assert_array_equal(getattr(back, name), getattr(cal, name))
    assert back.tilt_rad_per_nm == cal.tilt_rad_per_nm
    assert back.speed_lead_s == cal.speed_lead_s
    assert back.fit == cal.fit and back.effects == cal.effects and back.name == "unit-7"


def test_hash_covers_parameters_and_design_not_name_or_fit(baseline):
    cal = C.neutral(baseline, "a")
    assert cal.with_(name="b", fit={"x": 1}).hash32() == cal.hash32()
    assert cal.with_(offset_rad=np.full(6, 1e-6)).hash32() != cal.hash32()
    assert cal.with_(design_hash=cal.design_hash ^ 1).hash32() != cal.hash32()


def test_later_parameters_are_hashed_only_when_present(baseline):
    """A calibration without curves or a friction speed limit keeps the hash it had before
    they existed (boards and logs that report it stay recognised); setting one changes it."""
    cal = C.neutral(baseline, "a")
    for name in C._HASHED_WHEN_PRESENT:
        assert name not in cal.canonical()
    # The neutral calibration's hash as it was before the curves (it covers the design hash).
    assert cal.hash32() == 0x0EA94F52
    for name, shape in (("spring_curvature", (6, 2)), ("encoder_periodic_rad", (6, 8)),
                        ("friction_speed_limit_rad_s", (6,))):
        value = np.zeros(shape)
        value.flat[3] = 1e-4
        assert cal.with_(**{name: value}).hash32() != cal.hash32()
    assert cal.with_(speed_lead_s=1e-4).hash32() != cal.hash32()
    # A new calibration leads its friction's speed; the neutral one stays as it was.
    new = C.new_settings(baseline, "a")
    assert new.speed_lead_s == C.DEFAULT_SPEED_LEAD_S > 0
    # ... and four hysteresis plays (the board's most), its weights neutral.
    assert new.hysteresis_radii_counts == C.NEW_HYSTERESIS_RADII and len(C.NEW_HYSTERESIS_RADII) == 4
    assert new.hysteresis_nm.shape == (6, 4) and not new.hysteresis_nm.any()
    assert cal.hysteresis_radii_counts == C.DEFAULT_HYSTERESIS_RADII


def test_wrong_design_is_refused(baseline):
    cal = C.neutral(baseline)
    other = baseline.replace(lb_mm=121.0)
    with pytest.raises(C.CalibrationError, match="fitted for design"):
        cal.check_design(other)


def test_log_naming_another_calibration_or_design_is_refused(baseline):
    cal = C.neutral(baseline)
    C.check_log_meta({"design_hash": f"0x{baseline.hash32():08x}"}, baseline, cal)
    with pytest.raises(C.CalibrationError, match="recorded with design .* pass that design's "
                       "file with --design"):
        C.check_log_meta({"design_hash": "0x12345678"}, baseline, cal)
    with pytest.raises(C.CalibrationError, match="calibration"):
        C.check_log_meta({"calibration_hash": "0x12345678"}, baseline, cal)


@pytest.fixture(scope="module")
def good_text(baseline):
    return C.dumps(_random_cal(baseline, np.random.default_rng(1)))


@pytest.mark.parametrize("old,new,field", [
    ('name = "unit-7"', 'name = "a name far too long for the info record"', "name"),
    ("[spring]\nrate_ratio = [", "[spring]\nrate_kk = [", "spring.rate_kk"),
    ("offset_rad = [", "offset_rad = [1.0, ", "angle.offset_rad"),
    ("play_radii_counts = [16, 64, 256]", "play_radii_counts = [16, 16.5, 256]",
     "play_radii_counts"),
    ("tilt_rad_per_nm = ", "tilt_rad_per_nm = nan #", "tilt_rad_per_nm"),
    ('schema = "delta6-calibration/1"', 'schema = "delta6-log"', "schema"),
    ('effects = ["encoder_offset", "joint_friction"]', 'effects = ["thermal_drift"]', "effects"),
    ("curvature = [[", "curvature = [[0.1, 0.2, 0.3], [", "spring.curvature"),
    ("curvature = [[", "curvature = [[7.0, 0.1], [", "spring.curvature"),
    ("periodic_rad = [[", "periodic_rad = [[0.5, ", "angle.periodic_rad"),
])
def test_bad_fields_are_named(good_text, old, new, field):
    assert old in good_text
    with pytest.raises(C.CalibrationError, match=field.replace(".", r"\.")) as info:
        C.loads(good_text.replace(old, new, 1), "cal.toml")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("value, why", [(-1.0, "must be >= 0"), (500.0, "at most 100")])
def test_a_friction_speed_limit_is_a_speed(baseline, value, why):
    limit = np.full(6, 0.5)
    limit[3] = value
    with pytest.raises(C.CalibrationError, match=f"friction.speed_limit_rad_s.*{why}"):
        C.validate(C.neutral(baseline).with_(friction_speed_limit_rad_s=limit), "cal.toml")


def test_edited_parameters_are_caught_by_the_hash(good_text):
    lines = good_text.splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("rate_ratio"))
    lines[i] = "rate_ratio = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]"
    with pytest.raises(C.CalibrationError, match="edited"):
        C.loads("\n".join(lines))
    # Without the calibration's hash line (the first) the edit is accepted.
    h = next(k for k, ln in enumerate(lines) if ln.startswith("hash ="))
    cal = C.loads("\n".join(lines[:h] + lines[h + 1:]))
    assert list(cal.rate_ratio) == [1.0] * 6


@given(st.binary(max_size=400))
def test_random_bytes_give_a_calibration_error_only(data):
    text = data.decode("utf-8", errors="replace")
    with pytest.raises(C.CalibrationError):
        C.loads(text)


@given(st.integers(0, 10**6), st.integers(0, 255))
def test_mutated_files_load_or_fail_with_one_line(good_text, pos, byte):
    raw = bytearray(good_text.encode())
    raw[pos % len(raw)] = byte
    try:
        C.loads(raw.decode("utf-8", errors="replace"))
    except C.CalibrationError as exc:
        assert "\n" not in str(exc).strip() or "TOML" in str(exc)


def test_missing_file(tmp_path):
    with pytest.raises(C.CalibrationError, match="no such file"):
        C.load(tmp_path / "none.toml")


def test_a_byte_order_mark_is_not_an_error(baseline, tmp_path):
    cal = C.neutral(baseline, "unit-bom")
    path = tmp_path / "cal.toml"
    path.write_bytes(b"\xef\xbb\xbf" + C.dumps(cal).encode())
    assert C.load(path).hash32() == cal.hash32()


@pytest.mark.parametrize("name, ok", [("unit 7 (bench)", True), ('a"b\\c??/d e', True),
                                      ("../q", True), ("", False), ("  ", False),
                                      ("caf\u00e9", False), ("a\tb", False)])
def test_a_calibration_name_is_a_printable_label(good_text, name, ok):
    # What `calibrate -o "unit 7.toml"` named a calibration by default loads, even for host
    # use; only what the device-info record cannot carry is refused.
    text = good_text.replace('name = "unit-7"', f"name = {json.dumps(name)}", 1)
    if ok:
        assert C.loads(text, "cal.toml").name == name
    else:
        with pytest.raises(C.CalibrationError, match="name") as info:
            C.loads(text, "cal.toml")
        assert "\n" not in str(info.value)


@pytest.mark.parametrize("value, why", [(-0.01, "must be >= 0"), (0.5, "at most 0.1"),
                                        (float("nan"), "finite")])
def test_the_speed_lead_is_a_short_time(baseline, value, why):
    with pytest.raises(C.CalibrationError, match=f"friction.speed_lead_s.*{why}"):
        C.validate(C.neutral(baseline).with_(speed_lead_s=value), "cal.toml")


def test_a_ragged_table_is_named_as_such(good_text):
    with pytest.raises(C.CalibrationError) as info:
        C.loads(good_text.replace("curvature = [[", "curvature = [[0.1, 0.2, 0.3], [", 1),
                "cal.toml")
    assert str(info.value) == ("cal.toml: field 'spring.curvature': must be a table of numbers, "
                               "its rows of one length")
