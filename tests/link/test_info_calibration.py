"""INFO 1.1 carries the calibration the firmware applies, 1.2 its on-chip residual model; an
older device's shorter INFO still parses, as no calibration and no model."""
from __future__ import annotations

from delta6.link import protocol as P


def _info(**changes) -> P.Info:
    base = P.Info(request_id=3, protocol=P.VERSION, firmware=(1, 0, 0), mode=1,
                  design_hash=0x535534AF, design_name="delta6", full_scale=(1.0,) * 6,
                  lsb_mantissa=(1,) * 6, lsb_exponent=(-3,) * 6, rate_hz=250, max_rate_hz=350,
                  status=0, streaming=False, config_problem=0, baud=500000, serial_number=0,
                  zero_counts=(0,) * 6, tare=(0.0,) * 6, joint_limit_rad=0.5, boot_id=0x0102)
    return base._replace(**changes)


def test_calibration_round_trips():
    info = _info(calibration_hash=0xC2F65802, calibration_name="paper-unit")
    payload = P.unframe(P.encode_info(info)[:-1])
    assert len(payload) == P.RECORD_SIZES[P.RecordType.INFO]
    assert P.parse_payload(payload) == info


def test_a_1_0_info_reads_as_no_calibration():
    payload = P.unframe(P.encode_info(_info(calibration_hash=7, calibration_name="x"))[:-1])
    old = P.parse_payload(payload[:P.INFO_SIZE_1_0])
    assert old.calibration_hash == 0 and old.calibration_name == ""
    assert old.design_name == "delta6" and old.joint_limit_rad == 0.5
    assert old.config_problem == 0          # byte 79: reserved and 0 in 1.0


def test_the_model_round_trips_and_a_1_1_info_reads_as_no_model():
    info = _info(calibration_hash=0xC2F65802, calibration_name="paper-unit", boot_id=0x2A17,
                 model_hash=0x1234ABCD, model_name="unit-residual")
    payload = P.unframe(P.encode_info(info)[:-1])
    assert len(payload) == P.RECORD_SIZES[P.RecordType.INFO]
    assert P.parse_payload(payload) == info
    old = P.parse_payload(payload[:P.INFO_SIZE_1_1])
    assert old.model_hash == 0 and old.model_name == ""
    assert old.calibration_hash == 0xC2F65802 and old.calibration_name == "paper-unit"
    assert old.boot_id == 0x2A17
    assert P.unframe(P.encode_record(info, minor=1)[:-1]) == payload[:P.INFO_SIZE_1_1]
