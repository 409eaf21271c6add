"""The windowing and standardisation maths (numpy; shared by training and inference)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.learning.windows import (
    GAP_PERIODS,
    Normalisation,
    nominal_rate,
    segment_starts,
    time_split,
    window_index,
    windows,
)

RATE = 50.0


@st.composite
def sample_times(draw, max_rows=120):
    """Times at ``RATE`` with occasional lost samples and restarts."""
    n = draw(st.integers(1, max_rows))
    steps = draw(st.lists(st.sampled_from([1, 1, 1, 1, 2, 3, 40]), min_size=n, max_size=n))
    return np.cumsum(np.asarray(steps, float)) / RATE


@given(sample_times(), st.integers(1, 30))
def test_window_index_is_each_rows_own_recent_history(t, window):
    starts = segment_starts(t, RATE)
    idx = window_index(starts, window)
    rows = np.arange(len(t))
    assert idx.shape == (len(t), window)
    assert np.array_equal(idx[:, -1], rows)                     # newest = the row itself
    assert (np.diff(idx, axis=1) >= 0).all() and (np.diff(idx, axis=1) <= 1).all()
    assert (idx >= starts[:, None]).all()                       # never across a gap
    assert (idx[:, 0] == np.maximum(rows - window + 1, starts)).all()
    # within a segment no step is longer than the gap threshold
    inside = idx[:, 1:] > idx[:, :-1]
    assert (np.diff(t[idx], axis=1)[inside] <= GAP_PERIODS / RATE).all()


@given(sample_times())
def test_segments_start_exactly_after_long_steps(t):
    starts = segment_starts(t, RATE)
    new = np.r_[True, np.diff(t) > GAP_PERIODS / RATE]
    assert np.array_equal(starts == np.arange(len(t)), new)


def test_windows_pad_with_the_oldest_reading_of_the_segment():
    t = np.array([0.0, 0.02, 0.04, 1.0, 1.02])
    theta = np.arange(5.0)[:, None] * np.ones(6)
    win = windows(theta, t, RATE, window=3)
    assert win[:, :, 0].tolist() == [[0, 0, 0], [0, 0, 1], [0, 1, 2], [3, 3, 3], [3, 3, 4]]


def test_nominal_rate_ignores_gaps():
    t = np.r_[np.arange(100) / 50.0, 10 + np.arange(100) / 50.0]
    assert nominal_rate(t) == pytest.approx(50.0)


finite = st.floats(-0.6, 0.6, allow_nan=False, width=64)


@given(arrays(float, st.tuples(st.integers(2, 40), st.just(5), st.just(6)), elements=finite),
       arrays(float, st.tuples(st.just(1), st.just(6)), elements=st.floats(-30, 30)))
def test_normalisation_is_an_invertible_map_of_the_window(win, y0):
    target = y0 + win[:, -1, :] * 10
    norm = Normalisation.fit(win, target)
    x = norm.inputs(win).astype(float)
    newest = x[:, -1, :] * norm.theta_scale + norm.theta_mean
    back = x[:, :-1, :] * norm.delta_scale + newest[:, None, :]
    tol = 1e-6 * (1 + np.abs(win).max())
    assert np.allclose(newest, win[:, -1, :], atol=tol, rtol=1e-6)
    assert np.allclose(back, win[:, :-1, :], atol=tol, rtol=1e-6)
    assert np.allclose(norm.wrench(norm.targets(target)), target, atol=1e-5 * (1 + abs(target).max()),
                       rtol=1e-6)
    assert min(norm.theta_scale + norm.delta_scale + norm.target_scale) > 0
    assert Normalisation.from_json(norm.to_json()) == norm


@given(st.integers(0, 2**32 - 1), st.integers(50, 400),
       st.lists(st.floats(1e-3, 1.0), min_size=6, max_size=6))
def test_standardised_training_rows_have_zero_mean_and_unit_spread(seed, n, spread):
    win = np.random.default_rng(seed).normal(size=(n, 4, 6)) * spread
    target = np.sin(win[:, -1, :] * 3) + win[:, 0, :]
    norm = Normalisation.fit(win, target)
    x = norm.inputs(win).astype(float)
    z = norm.targets(target).astype(float)
    assert np.allclose(x[:, -1, :].mean(0), 0, atol=1e-5)
    assert np.allclose(x[:, -1, :].std(0), 1, atol=1e-4)
    assert np.allclose(z.mean(0), 0, atol=1e-5) and np.allclose(z.std(0), 1, atol=1e-4)
    delta = x[:, :-1, :].reshape(-1, 6)
    assert np.allclose(delta.std(0), 1, atol=1e-4)


@pytest.mark.parametrize("text, message", [
    ('{"theta_mean": [0, 0, 0, 0, 0, 0]}', "theta_scale"),
    ('{"theta_mean": [0,0,0,0,0], "theta_scale": [1,1,1,1,1,1], "delta_scale": [1,1,1,1,1,1],'
     ' "target_mean": [0,0,0,0,0,0], "target_scale": [1,1,1,1,1,1]}', "six"),
    ('{"theta_mean": [0,0,0,0,0,0], "theta_scale": [1,1,1,1,1,0], "delta_scale": [1,1,1,1,1,1],'
     ' "target_mean": [0,0,0,0,0,0], "target_scale": [1,1,1,1,1,1]}', "theta_scale must lie"),
    # implausible scales: a numpy warning then a misleading message, or a 300-digit table cell
    ('{"theta_mean": [0,0,0,0,0,0], "theta_scale": [1,1,1,1,1,1e-300], "delta_scale": '
     '[1,1,1,1,1,1], "target_mean": [0,0,0,0,0,0], "target_scale": [1,1,1,1,1,1]}',
     r"theta_scale must lie in 1e-09\.\.1e\+06"),
    ('{"theta_mean": [0,0,0,0,0,0], "theta_scale": [1,1,1,1,1,1], "delta_scale": '
     '[1,1,1,1,1,1], "target_mean": [0,0,0,0,0,0], "target_scale": [1,1,1,1,1,1e300]}',
     "target_scale must lie in"),
    ('{"theta_mean": [0,0,0,0,0,0], "theta_scale": [1,1,1,1,1,1], "delta_scale": '
     '[1,1,1,1,1,1], "target_mean": [0,0,0,0,0,1e300], "target_scale": [1,1,1,1,1,1]}',
     "target_mean must lie in"),
])
def test_normalisation_from_bad_json_is_refused(text, message):
    with pytest.raises((KeyError, ValueError), match=message):
        Normalisation.from_json(text)


@given(st.integers(2, 10**6), st.floats(0.01, 0.99))
def test_time_split_leaves_rows_on_both_sides(n, holdout):
    split = time_split(n, holdout)
    assert 1 <= split <= n - 1
    assert abs((n - split) - n * holdout) <= 1 or split in (1, n - 1)
