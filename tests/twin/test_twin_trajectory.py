"""The robot's random trajectory: covers the box, reverses every joint often, at varied
speeds, with bounded accelerations; deterministic; its rates are its derivative."""
from __future__ import annotations

import numpy as np
import pytest

from delta6 import twin
from delta6.twin.streams import stream

LIMIT = np.pi / 6


def make(seed=1, duration=600.0, **kw):
    return twin.RandomTrajectory(LIMIT, duration, stream(seed, "trajectory"),
                                 twin.TrajectorySettings(**kw))


def sample(path, duration=600.0, rate=200.0):
    t = np.arange(0, duration, 1 / rate)
    return (t, *path.evaluate(t))


def test_deterministic_for_a_seed_and_different_across_seeds():
    t, q1, _ = sample(make(1), 60)
    _, q2, _ = sample(make(1), 60)
    _, q3, _ = sample(make(2), 60)
    assert np.array_equal(q1, q2) and not np.array_equal(q1, q3)


def test_covers_most_of_the_joint_box_without_leaving_it():
    _, q, _ = sample(make(3))
    assert np.all(np.abs(q) <= 0.9 * LIMIT + 1e-12)
    assert np.all(np.ptp(q, axis=0) > 0.8 * 2 * 0.9 * LIMIT)
    # Both outer quarters of every joint are visited a fair share of the time.
    assert np.all((q > 0.5 * LIMIT).mean(axis=0) > 0.05)
    assert np.all((q < -0.5 * LIMIT).mean(axis=0) > 0.05)


def test_every_joint_reverses_often_at_varied_speeds():
    t, q, qd = sample(make(4))
    moving = np.abs(qd) > 1e-3
    reversals = np.sum(np.diff(np.sign(qd), axis=0) != 0, axis=0)
    assert np.all(reversals / 10.0 > 10)          # more than 10 per minute per joint
    speeds = np.abs(qd[moving.all(axis=1)])
    assert np.percentile(speeds, 95) > 5 * np.percentile(speeds, 25)
    assert np.abs(qd).max() < 1.0 + 0.02 * 2 * np.pi * 1.2 + 0.01   # speed limit + dither


def test_rates_are_the_derivative_and_accelerations_are_bounded():
    path = make(5)
    t, q, qd = sample(path, 300, rate=1000)
    assert np.allclose(np.gradient(q, t, axis=0)[1:-1], qd[1:-1], atol=2e-4)
    qdd = np.gradient(qd, t, axis=0)
    s = path.settings
    dither = s.dither_rad * ((2 * np.pi * s.dither_max_hz) ** 2 + 1.0)
    assert np.abs(qdd[1:-1]).max() < s.accel_max_rad_s2 + dither


def test_starts_at_rest_and_scale_scales_the_path():
    t = np.linspace(-1, 50, 2001)
    q, qd = make(6, 50).evaluate(t)
    assert np.all(q[t <= 0] == 0) and np.all(qd[t < 0] == 0)
    half, half_rate = make(6, 50, scale=0.5).evaluate(t)
    assert np.allclose(half, 0.5 * q) and np.allclose(half_rate, 0.5 * qd)


def test_bad_settings_are_refused():
    for bad in (dict(coverage=0), dict(move_min_s=2, move_max_s=1),
                dict(scale=2), dict(dither_rad=-0.1)):
        with pytest.raises(ValueError):
            make(1, 10, **bad)


@pytest.mark.parametrize("limit", [0.01, 0.015, 0.022, 0.05])
def test_a_narrow_box_scales_the_dither_and_stays_inside(limit):
    """Every box a design may have (down to 0.01 rad) can be simulated: the dither shrinks to
    a share of the covered range instead of refusing it; the paper's box keeps 0.02 rad."""
    path = twin.RandomTrajectory(limit, 120.0, stream(4, "trajectory"), twin.TrajectorySettings())
    _, q, _ = sample(path, 120.0)
    assert np.all(np.abs(q) <= 0.9 * limit + 1e-12)
    assert np.all(np.ptp(q, axis=0) > 0.5 * 0.9 * limit)
    assert make(1, 10).dither_rad == twin.TrajectorySettings().dither_rad
