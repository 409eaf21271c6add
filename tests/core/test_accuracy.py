"""Table V's arithmetic: the error in % FS and its percentiles, and the reference a late rig
would have read (``advanced``)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.core import accuracy


@given(st.floats(0.0, 0.2), st.floats(0.5, 3.0), st.floats(-2.0, 2.0))
def test_a_straight_line_advanced_by_the_latency_is_exact_where_it_is_known(latency, slope,
                                                                           offset):
    t = np.arange(0, 5.0, 0.02)
    values = np.stack([offset + slope * t, -slope * t], axis=1)
    shifted, keep = accuracy.advanced(t, values, latency)
    assert keep.tolist() == (t + latency <= t[-1] + 5e-9).tolist()
    assert shifted.shape == (int(keep.sum()), 2)
    np.testing.assert_allclose(shifted[:, 0], offset + slope * (t[keep] + latency), atol=1e-9)
    np.testing.assert_allclose(shifted[:, 1], -slope * (t[keep] + latency), atol=1e-9)


def test_advanced_interpolates_between_rows_and_drops_the_tail():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    values = np.array([[0.0], [10.0], [30.0], [60.0]])
    shifted, keep = accuracy.advanced(t, values, 0.5)
    assert keep.tolist() == [True, True, True, False]
    assert shifted[:, 0].tolist() == [5.0, 20.0, 45.0]
    same, keep0 = accuracy.advanced(t, values, 0.0)
    assert keep0.all() and np.array_equal(same, values)


def test_percentiles_are_of_the_error_in_percent_of_full_scale():
    reference = np.zeros((101, 6))
    estimate = np.tile(np.arange(101.0)[:, None], (1, 6)) * 0.01   # 0 .. 1 N
    fs = np.full(6, 2.0)
    table = accuracy.percentiles(estimate, reference, fs, [50, 99, 100])
    assert table["p50"] == pytest.approx([25.0] * 6)               # 0.5 N of 2 N
    assert table["p99"] == pytest.approx([49.5] * 6)
    assert table["p100"] == pytest.approx([50.0] * 6)
