"""CRC, COBS, scaling and quantisation: Python against the firmware's C++, property-based."""
from __future__ import annotations

import binascii
import ctypes

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from delta6.core.design import load
from delta6.core.model import wrench
from delta6.link import cobs
from delta6.link import protocol as P
from delta6.link import wirescale as W
from delta6.link.crc import crc16, crc16_rows
from delta6.sim.simdevice import native_library

from conftest import DESIGN_FILES


@pytest.fixture(scope="module")
def lib():
    return native_library()


@given(st.binary(max_size=300))
def test_crc_matches_binascii_and_cpp(lib, data):
    assert crc16(data) == binascii.crc_hqx(data, 0xFFFF) == lib.d6_crc16(data, len(data))


def test_crc_check_value():
    # CRC-16/CCITT-FALSE of "123456789" is 0x29B1 by definition of the algorithm.
    assert crc16(b"123456789") == 0x29B1


@given(st.integers(1, 40), st.integers(0, 31), st.randoms(use_true_random=False))
def test_crc_rows_matches_bytewise(rows, length, rnd):
    data = np.frombuffer(rnd.randbytes(rows * length), dtype=np.uint8).reshape(rows, length)
    expected = [crc16(row.tobytes()) for row in data]
    assert crc16_rows(data).tolist() == expected


@given(st.binary(max_size=600))
def test_cobs_round_trip_and_no_zero(data):
    encoded = cobs.encode(data)
    assert b"\x00" not in encoded
    assert cobs.decode(encoded) == data
    assert len(encoded) <= len(data) + 1 + len(data) // 254


@given(st.binary(max_size=254))
@example(b"")
@example(b"\x00")
@example(bytes(range(1, 255)))            # one full 254-byte block
@example(bytes(range(1, 255))[:253] + b"\x00")
def test_cpp_in_place_encoder_matches_python_byte_for_byte(lib, data):
    buf = ctypes.create_string_buffer(b"\xAA" + data, len(data) + 1)
    n = lib.d6_cobs_encode_in_place(buf, len(data))
    assert buf.raw[:n] == cobs.encode(data)


def test_cpp_in_place_encoder_refuses_long_input(lib):
    buf = ctypes.create_string_buffer(300)
    assert lib.d6_cobs_encode_in_place(buf, 255) == 0


@given(st.binary(max_size=600))
def test_cpp_decoder_decodes_python_encoding(lib, data):
    encoded = cobs.encode(data)
    buf = ctypes.create_string_buffer(encoded, len(encoded))
    n = lib.d6_cobs_decode_in_place(buf, len(encoded))
    assert n == len(data) and buf.raw[:n] == data


@given(st.binary(min_size=1, max_size=80))
def test_invalid_cobs_is_rejected_alike(lib, frame):
    """Both decoders accept exactly the same frames and decode them to the same bytes."""
    python = cobs.decode(frame)
    buf = ctypes.create_string_buffer(frame, len(frame))
    n = lib.d6_cobs_decode_in_place(buf, len(frame))
    if python is None:
        assert n == -1
    else:
        assert buf.raw[:n] == python


# --- scaling ------------------------------------------------------------------------------

def cpp_scale(lib, fs):
    m, e = ctypes.c_uint8(), ctypes.c_int8()
    lib.d6_scale(fs, ctypes.byref(m), ctypes.byref(e))
    return m.value, e.value


boundaries = [np.float32(m) * np.float32(f"1e{e}") * np.float32(32767) / np.float32(1.25)
              for e in range(-6, 4) for m in (1, 2, 5)]


@given(st.one_of(st.floats(0, 2e8, width=32), st.sampled_from(boundaries),
                 st.sampled_from(boundaries).map(lambda b: float(np.nextafter(np.float32(b), np.float32(0)))),
                 st.sampled_from(boundaries).map(lambda b: float(np.nextafter(np.float32(b), np.float32(1e9))))))
def test_scale_choice_matches_cpp_even_at_boundaries(lib, fs):
    assert W.choose_scale(fs) == cpp_scale(lib, fs)


@given(st.floats(1e-3, 1e7))
def test_scale_is_the_smallest_step_with_headroom(fs):
    m, e = W.choose_scale(fs)
    step = P.lsb_value(m, e)
    assert step * 32767 >= 1.25 * fs * (1 - 1e-6)
    steps = sorted(P.lsb_value(mm, ee) for ee in range(-6, 4) for mm in (1, 2, 5))
    smaller = [s for s in steps if s < step]
    if smaller:
        assert smaller[-1] * 32767 < 1.25 * fs * (1 + 1e-6)


@given(st.floats(allow_nan=True, allow_infinity=True, width=32),
       st.sampled_from([(1, -3), (2, -3), (5, -4), (2, -5), (1, 0)]))
@example(0.5, (1, 0))      # exact halves: away from zero on both sides, as the firmware does
@example(-0.5, (1, 0))
@example(2.5, (1, 0))
@example(-32766.5, (1, 0))
def test_quantize_matches_cpp_exactly(lib, value, scale):
    lsb = W.float32_lsb(*scale)
    inverse = np.float32(1) / lsb
    clipped = ctypes.c_int()
    expected = lib.d6_quantize(value, float(inverse), ctypes.byref(clipped))
    q, c = W.quantize(np.array([value]), lsb)
    assert int(q[0]) == expected
    assert bool(c[0]) == bool(clipped.value)
    if scale == (1, 0) and abs(value) <= 32767 and value % 1 == 0.5:
        assert abs(expected) == abs(value) + 0.5


@given(st.floats(-30, 30, width=32))
def test_quantisation_error_is_at_most_half_a_step(value):
    lsb = W.float32_lsb(1, -3)
    q, clipped = W.quantize(np.array([value]), lsb)
    assert not clipped[0]
    # The device multiplies by a float32 reciprocal of the step (a division costs ~2k AVR
    # cycles a sample): the step, its reciprocal and the product each round by at most 2^-24
    # relative, so the error is half a step plus at most 3 * 2^-24 of the value.
    assert abs(int(q[0]) * P.lsb_value(1, -3) - value) <= 0.5e-3 + abs(value) * 3 * 2.0**-24


def test_link_limits():
    assert P.link_rate_limit(500_000, P.Mode.WRENCH) == 1800
    assert P.link_rate_limit(500_000, P.Mode.WRENCH_RAW) == 1216
    assert P.link_rate_limit(115_200, P.Mode.WRENCH) == 414
    assert P.max_rate_for_link(1_000_000) == pytest.approx(4000)


@given(st.lists(st.integers(0, 16383), min_size=6, max_size=6),
       st.lists(st.integers(0, 16383), min_size=6, max_size=6))
@example([8192, 0, 8191, 16383, 0, 1], [0, 8192, 16383, 8191, 8193, 8193])   # half turns
def test_count_delta_is_the_short_way_round(counts, zero):
    d = P.count_delta(counts, zero)
    assert ((np.asarray(zero) + d - np.asarray(counts)) % 16384 == 0).all()
    assert (d >= -8192).all() and (d < 8192).all()


def test_count_delta_at_the_half_turn_is_minus_8192_as_the_firmware_has_it():
    assert P.count_delta([8192, 0, 16383, 0, 8191, 8193],
                         [0, 8192, 8191, 1, 16383, 1]).tolist() == [-8192, -8192, -8192, -1,
                                                                     -8192, -8192]


def test_theta_values_are_nan_for_failed_reads_and_missing_counts_only():
    counts = np.array([[0, 100, 200, 300, 400, 500], [P.NO_COUNTS, 1, 2, 3, 4, 5]])
    status = np.array([0b000100, 0])
    theta = P.theta_values(counts, status, np.zeros(6, dtype=np.int64))
    assert np.isnan(theta[0, 2]) and np.isnan(theta[1, 0])
    assert np.isfinite(np.delete(theta[0], 2)).all() and np.isfinite(theta[1, 1:]).all()
    assert theta[0, 1] == pytest.approx(100 * P.COUNT_RAD)


def test_wrench_values_are_nan_for_invalid_samples_and_axes_only():
    counts = np.array([[1, 2, 3, 4, 5, P.INVALID_VALUE], [1, 2, 3, 4, 5, 6]])
    status = np.array([0, P.Status.WRENCH_INVALID])
    w = P.wrench_values(counts, status, np.full(6, 0.5))
    assert np.isnan(w[0, 5]) and np.isnan(w[1]).all()
    assert w[0, :5].tolist() == [0.5, 1.0, 1.5, 2.0, 2.5]


def test_info_round_trips_through_its_encoder():
    info = P.Info(request_id=9, protocol=(1, 0), firmware=(0, 1, 2), mode=P.Mode.WRENCH_RAW,
                  design_hash=0x535534AF, design_name="delta6", full_scale=(1.5,) * 6,
                  lsb_mantissa=(1, 2, 5, 1, 2, 5), lsb_exponent=(-3, -3, -3, -5, -5, -5),
                  rate_hz=500, max_rate_hz=2000, status=P.Status.TARE_ACTIVE, streaming=True,
                  config_problem=P.ConfigProblem.BAD_CRC, baud=500000,
                  serial_number=7, zero_counts=(1, 2, 3, 4, 5, 16383), tare=(0.5,) * 6,
                  joint_limit_rad=0.5)
    payload = P.unframe(P.encode_info(info)[:-1])
    assert P.parse_payload(payload) == info
    assert np.allclose(info.lsb, [1e-3, 2e-3, 5e-3, 1e-5, 2e-5, 5e-5], rtol=0, atol=1e-18)


def test_short_or_unknown_payloads_are_rejected():
    with pytest.raises(P.ProtocolError, match=f"needs {P.RECORD_SIZES[P.RecordType.WRENCH]}"):
        P.parse_payload(bytes([P.RecordType.WRENCH]) + bytes(10))
    with pytest.raises(P.ProtocolError, match="unknown record type 0x7e"):
        P.parse_payload(bytes([0x7E, 0, 0]))
    # A newer minor version may append fields: the known prefix still parses.
    longer = P.RECORD_LAYOUTS[P.RecordType.WRENCH].pack(
        type=P.RecordType.WRENCH, seq=5, time_us=6, status=0, wrench=(1, 2, 3, 4, 5, 6)) + b"\x01\x02"
    assert P.parse_payload(longer).seq == 5


@pytest.mark.parametrize("path", DESIGN_FILES, ids=lambda p: p.stem)
def test_one_encoder_count_is_never_lost_on_the_wire(path):
    """For every shipped design, the smallest one-count change anywhere in the joint box moves
    some axis by at least one LSB, and the range holds 1.25 x full scale."""
    design = load(path)
    check = W.resolution_check(design)
    assert check.force_margin >= 1.0 and check.moment_margin >= 1.0, check
    assert np.all(check.headroom >= 1.25) and np.all(check.headroom < 3.2)
    # The minima are real: random configurations never step by less.
    rng = np.random.default_rng(0)
    theta = rng.uniform(-design.joint_limit_rad, design.joint_limit_rad, (4000, 6))
    w0 = wrench(design, theta)
    for j in range(6):
        bumped = theta.copy()
        bumped[:, j] += P.COUNT_RAD
        step = wrench(design, bumped) - w0
        if j < 3:
            assert np.linalg.norm(step[:, :3], axis=1).min() >= check.force_step_min * (1 - 1e-6)
        else:
            assert np.linalg.norm(step[:, 3:], axis=1).min() >= check.moment_step_min * (1 - 1e-6)


@given(st.sampled_from([P.RecordType.INFO, P.RecordType.TELEMETRY]), st.integers(1, 300))
def test_a_record_is_read_at_exactly_the_lengths_a_version_sends(kind, length):
    """docs/protocol.md section 11: the sizes of older minor versions, or the current one and
    longer; any other length is a record cut short."""
    payload = bytes([kind]) + bytes(length - 1)
    sizes = P.RECORD_SIZES_BY_MINOR[kind]
    accepted = length in sizes or length >= P.RECORD_SIZES[kind]
    try:
        P.parse_payload(payload)
    except P.ProtocolError:
        assert not accepted
    else:
        assert accepted
