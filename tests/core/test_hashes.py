"""The one parser of 32-bit hashes written as hexadecimal text (calibration files, model files,
model cards)."""
from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.core.hashes import parse_hash32


@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_any_32_bit_hash_round_trips_whatever_its_case(value, upper, prefix):
    text = f"{value:08x}"
    text = (text.upper() if upper else text)
    assert parse_hash32(("0x" if prefix else "") + text) == value


@pytest.mark.parametrize("value, why", [(123, "hex string"), ("0xzz", "not a hexadecimal"),
                                        ("", "not a hexadecimal"), ("0x1234567890", "32 bits"),
                                        ("-0x1", "32 bits"), (None, "hex string")])
def test_anything_else_says_what_is_wrong_in_one_line(value, why):
    with pytest.raises(ValueError, match=why) as info:
        parse_hash32(value)
    assert "\n" not in str(info.value)


@given(st.text(max_size=60))
def test_text_is_a_hash_or_a_value_error(text):
    try:
        value = parse_hash32(text)
    except ValueError as exc:
        assert "\n" not in str(exc)
    else:
        assert 0 <= value < 2**32
