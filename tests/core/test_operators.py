"""The blocked scans (``delta6.core.operators``) equal the sample-by-sample recurrences, and the
play operator has the properties that make the twin's hysteresis and backlash, and the
diagnosis's history features, rate-independent."""
from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.core.operators import affine_scan, clamp_scan, first_order, play

lengths = st.integers(0, 300)
tails = st.sampled_from([(), (1,), (3,), (2, 5), (17,)])
finite = st.floats(-10, 10, allow_nan=False)


def loop(step, x0, n):
    out, x = [], x0
    for i in range(n):
        x = step(i, x)
        out.append(x)
    return np.array(out).reshape((n,) + np.shape(x0))


@given(st.data(), lengths, tails)
def test_affine_scan_equals_the_recurrence(data, n, tail):
    a = data.draw(arrays(float, (n,) + tail, elements=st.floats(-1.5, 1.5)))
    b = data.draw(arrays(float, (n,) + tail, elements=finite))
    x0 = data.draw(arrays(float, tail, elements=finite))
    want = loop(lambda i, x: a[i] * x + b[i], x0, n)
    assert np.allclose(affine_scan(a, b, x0), want, rtol=1e-9, atol=1e-9)


@given(st.data(), lengths, tails)
def test_clamp_scan_equals_the_recurrence(data, n, tail):
    lo = data.draw(arrays(float, (n,) + tail, elements=finite))
    width = data.draw(arrays(float, (n,) + tail, elements=st.floats(0, 5)))
    x0 = data.draw(arrays(float, tail, elements=finite))
    hi = lo + width
    want = loop(lambda i, x: np.minimum(np.maximum(x, lo[i]), hi[i]), x0, n)
    assert np.array_equal(clamp_scan(lo, hi, x0), want)


@given(arrays(float, st.integers(1, 200), elements=st.floats(-1, 1)), st.floats(0, 0.5))
def test_play_output_stays_within_the_radius(x, r):
    y = play(x, r)
    assert np.all(np.abs(x - y) <= r + 1e-12)
    assert y[0] == x[0]
    # It only moves when pushed: a step of y is never larger than the step of x.
    assert np.all(np.abs(np.diff(y)) <= np.abs(np.diff(x)) + 1e-12)


@given(arrays(float, st.integers(2, 60), elements=st.floats(-1, 1)), st.floats(0, 0.3),
       st.integers(2, 7))
def test_play_is_rate_independent(x, r, k):
    """Sampling the same piecewise-linear input more finely changes nothing at the original
    samples: only the path matters, not the time it took."""
    fine = np.concatenate([np.linspace(x[i], x[i + 1], k, endpoint=False)
                           for i in range(len(x) - 1)] + [x[-1:]])
    assert np.allclose(play(fine, r)[::k], play(x, r), atol=1e-12)


def test_play_stands_still_after_a_reversal_then_follows():
    x = np.concatenate([np.linspace(0, 1, 101), np.linspace(1, 0, 101)[1:]])
    y = play(x, 0.1)
    assert np.allclose(y[:101], np.maximum(x[:101] - 0.1, 0.0))
    back = y[101:]
    assert np.all(back[:19] == y[100])               # 0.2 of travel: the whole play
    assert np.allclose(back[21:], x[122:] + 0.1)


@given(arrays(float, st.integers(1, 120), elements=st.floats(-1, 1)),
       st.lists(st.floats(0, 0.5), min_size=1, max_size=4))
def test_play_radii_broadcast_like_copies_of_the_input(x, radii):
    """One operator per radius on a broadcast input equals each radius on its own."""
    wide = play(x[:, None], np.array(radii))
    for i, r in enumerate(radii):
        assert np.array_equal(wide[:, i], play(x, r))


@given(arrays(float, st.integers(1, 200), elements=finite), st.floats(0, 1))
def test_first_order_equals_the_recurrence(x, a):
    want = loop(lambda i, y: a * y + (1.0 - a) * x[i], x[0], len(x))
    assert np.allclose(first_order(x, a), want, rtol=1e-9, atol=1e-9)
    assert np.allclose(first_order(x, a, 2.0)[0], a * 2.0 + (1.0 - a) * x[0])
