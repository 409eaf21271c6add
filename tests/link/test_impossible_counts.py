"""Raw counts a 14-bit encoder never reads (16384..65535 fit in the wire's u16) are no angle:
left empty and counted, as a failed read is, offline (decode) and live (Device) alike."""
from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.link import protocol as P
from delta6.link.bulkdecode import decode_capture
from delta6.link.device import Device

from support.streams import an_info

rows = st.lists(st.lists(st.integers(0, 65535), min_size=6, max_size=6), min_size=1, max_size=8)


@settings(max_examples=60, deadline=None)
@given(rows)
def test_an_angle_exactly_where_the_count_is_a_14_bit_one(counts):
    info = an_info(mode=P.Mode.WRENCH_RAW, zero_counts=(100, 0, 16383, 5, 8000, 0))
    frames = [P.encode_wrench(i, 1000 + 4000 * i, 0, (0,) * 6, c) for i, c in enumerate(counts)]
    capture = decode_capture(P.encode_info(info) + b"".join(frames))
    offline = capture.theta(info.zero_counts)
    counts = np.array(counts)
    possible = counts < P.COUNTS_PER_TURN
    assert np.array_equal(np.isfinite(offline), possible)
    assert np.array_equal(offline[possible],
                          P.counts_to_theta(counts, info.zero_counts)[possible])
    with Device("loop://", handshake=False, timeout=0.2, retries=0) as dev:
        dev._serial.write(P.encode_info(info) + b"".join(frames))
        live = dev.samples(2.0)
        got = np.array([next(live).theta for _ in frames])
        assert dev.health.impossible_counts == int((~possible).sum())
    assert np.array_equal(got, offline, equal_nan=True)
