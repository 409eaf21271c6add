"""INFO 1.1 carries the calibration the firmware applies; a 1.0 device's shorter INFO still
parses, as no calibration."""
from __future__ import annotations

from delta6.link import protocol as P


def _info(**changes) -> P.Info:
    base = P.Info(request_id=3, protocol=P.VERSION, firmware=(1, 0, 0), mode=1,
                  design_hash=0x535534AF, design_name="delta6", full_scale=(1.0,) * 6,
                  lsb_mantissa=(1,) * 6, lsb_exponent=(-3,) * 6, rate_hz=250, max_rate_hz=350,
                  status=0, streaming=False, baud=500000, serial_number=0,
                  zero_counts=(0,) * 6, tare=(0.0,) * 6, joint_limit_rad=0.5)
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
