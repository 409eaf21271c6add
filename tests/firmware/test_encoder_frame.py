"""The encoder frame, implemented twice: what the virtual board's sensor model sends
(tools/simavr/virtual_board/frame.c) must be what the firmware's check
(firmware/lib/delta6_core/src/delta6_encoder.h) reads, for every count and every fault; and
the firmware's check follows the rules of the toolchain note for any pair of words."""
from __future__ import annotations

import ctypes

import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.build.nativebuild import ROOT, load_library
from delta6.sim.virtualboard import HARNESS_DIR

CORE = ROOT / "firmware" / "lib" / "delta6_core" / "src"
OK, BIT_ERROR, FIELD_STRONG, FIELD_WEAK, SENSOR_ERROR = range(5)
NONE, BITERROR, WEAK, STRONG, NOANSWER = range(5)


@pytest.fixture(scope="module")
def lib():
    lib = load_library("encoder_frame", [ROOT / "tests" / "native" / "encoder_shim.cpp",
                                         HARNESS_DIR / "frame.c"], [CORE, HARNESS_DIR])
    lib.d6_decode_frame.restype = ctypes.c_uint8
    lib.d6_decode_frame.argtypes = [ctypes.c_uint16, ctypes.c_uint16,
                                    ctypes.POINTER(ctypes.c_uint16)]
    lib.d6_valid_word.restype = ctypes.c_uint16
    lib.d6_valid_word.argtypes = [ctypes.c_uint16]
    lib.vb_frame.restype = ctypes.c_uint32
    lib.vb_frame.argtypes = [ctypes.c_uint16, ctypes.c_int, ctypes.c_uint]
    return lib


def decode(lib, word: int, inverse: int) -> tuple[int, int | None]:
    count = ctypes.c_uint16(0xBEEF)
    fault = lib.d6_decode_frame(word, inverse, ctypes.byref(count))
    if fault:
        assert count.value == 0xBEEF, "a failed read must not touch the count"
        return fault, None
    return fault, count.value


def reference(word: int, inverse: int) -> tuple[int, int | None]:
    """The rules, written out: inverse check, then the two status bits."""
    if (word + inverse + 1) % 65536 != 0:
        return BIT_ERROR, None
    if word & 3 == 1:
        return OK, word >> 2
    if word & 3 == 2 and word & 0x10:
        return FIELD_STRONG, None
    if word & 3 == 2 and word & 0x20:
        return FIELD_WEAK, None
    return SENSOR_ERROR, None


def split(frame: int) -> tuple[int, int]:
    return frame >> 16, frame & 0xFFFF


def test_every_count_round_trips(lib):
    for count in range(16384):
        frame = lib.vb_frame(count, NONE, 0)
        assert split(frame)[0] == lib.d6_valid_word(count)
        assert decode(lib, *split(frame)) == (OK, count)


@given(st.integers(0, 16383), st.integers(0, 31))
def test_any_flipped_bit_is_a_bit_error(lib, count, flip):
    frame = lib.vb_frame(count, BITERROR, flip)
    assert bin(frame ^ lib.vb_frame(count, NONE, 0)).count("1") == 1
    assert decode(lib, *split(frame)) == (BIT_ERROR, None)


@given(st.integers(0, 16383))
def test_field_faults_are_reported_as_such(lib, count):
    assert decode(lib, *split(lib.vb_frame(count, WEAK, 0))) == (FIELD_WEAK, None)
    assert decode(lib, *split(lib.vb_frame(count, STRONG, 0))) == (FIELD_STRONG, None)


def test_a_silent_sensor_is_a_bit_error(lib):
    # No answer: the line stays at its pull-up (all ones) or is stuck low (all zeros).
    assert decode(lib, 0xFFFF, 0xFFFF) == (BIT_ERROR, None)
    assert decode(lib, 0x0000, 0x0000) == (BIT_ERROR, None)


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFFFF))
def test_decoder_follows_the_rules_for_any_pair(lib, word, inverse):
    assert decode(lib, word, inverse) == reference(word, inverse)


@given(st.integers(0, 0xFFFF))
def test_decoder_follows_the_rules_for_intact_pairs(lib, word):
    # Random pairs are almost never intact; these always are, so every status is exercised.
    inverse = ~word & 0xFFFF
    assert decode(lib, word, inverse) == reference(word, inverse)
