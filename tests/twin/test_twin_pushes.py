"""The one-axis-at-a-time path (``twin.pushes.AxisPushes``): a robot pushing, never jumping."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.twin.pushes import AxisPushes, PushSettings
from delta6.twin.streams import stream


@settings(max_examples=25)
@given(st.integers(0, 10_000), st.floats(30.0, 1200.0))
def test_the_pushes_follow_one_another_and_the_path_never_jumps(baseline, seed, duration):
    path = AxisPushes(baseline, duration, stream(seed, "pushes"))
    starts, lengths = path.starts, path.lengths
    # One move after the other (at rest between the axes' stretches), each from the target
    # of the one before.
    assert np.all(np.diff(starts) > 0)
    assert np.all(starts[1:] >= starts[:-1] + lengths[:-1] - 1e-9)
    assert np.allclose(path.origins[1:], path.targets[:-1])
    # Every push is back at rest before the next axis's stretch begins.
    stretch = duration / 6.0
    assert starts[-1] + lengths[-1] <= duration + 1e-9
    for axis in range(6):
        inside = (starts >= axis * stretch - 1e-9) & (starts < (axis + 1) * stretch - 1e-9)
        assert inside.any()
        last = np.flatnonzero(inside)[-1]
        assert starts[last] + lengths[last] <= (axis + 1) * stretch + 1e-9
        assert np.all(path.targets[last] == 0.0)
    # Sampled finely, the pose moves by no more than the fastest ramp allows.
    t = np.linspace(0.0, duration, 200_001)
    q, _ = path.evaluate(t)
    fastest = 1.875 * 2 * baseline.joint_limit_rad / lengths.min()      # quintic peak speed
    assert np.abs(np.diff(q, axis=0)).max() <= fastest * (t[1] - t[0]) * 1.01


def test_each_axis_is_pushed_both_ways_on_a_long_enough_run(baseline):
    s = PushSettings()
    longest_cycle = 2 * (s.ramp_max_s + s.hold_max_s)
    path = AxisPushes(baseline, 6 * 2 * longest_cycle, stream(3, "pushes"))
    stretch = 2 * longest_cycle
    for axis in range(6):
        inside = (path.starts >= axis * stretch) & (path.starts < (axis + 1) * stretch)
        pushes = path.targets[inside][np.any(path.targets[inside] != 0.0, axis=1)]
        largest = np.argmax(np.abs(pushes[0]))
        assert {np.sign(p[largest]) for p in pushes} == {-1.0, 1.0}


def test_a_run_without_duration_is_refused(baseline):
    for duration in (0.0, -5.0, float("nan")):
        with pytest.raises(ValueError, match="positive duration"):
            AxisPushes(baseline, duration, stream(1, "pushes"))


def test_a_long_run_pushes_slowly(baseline):
    """From 400 s on, the pushes are sped up by at most the longest push over a stretch."""
    s = PushSettings()
    for seed in range(5):
        path = AxisPushes(baseline, 400.0, stream(seed, "pushes"))
        ramps = path.lengths[0::2]                      # ramp, hold, ramp, hold, ...
        assert ramps.min() >= s.ramp_min_s * (400.0 / 6) / (400.0 / 6 + 2 * (s.ramp_max_s
                                                                          + s.hold_max_s))
