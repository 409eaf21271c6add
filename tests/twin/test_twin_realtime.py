"""Driving a virtual board: the real-time encoder stream, raw counts, the replay file."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6 import twin
from delta6.core import model
from delta6.link import protocol as P
from delta6.link.logfile import read_log
from delta6.sim import simdevice


class FakeClock:
    def __init__(self):
        self.now = 100.0
        self.sleeps = []

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        assert seconds > 0
        self.sleeps.append(seconds)
        self.now += seconds


@pytest.fixture(scope="module")
def short_run(baseline):
    return twin.simulate(baseline, [twin.make_effect("backlash", 1)], duration_s=2, seed=1)


def test_realtime_stream_paces_the_samples(short_run):
    clock = FakeClock()
    out = list(twin.iter_realtime(short_run, clock=clock, sleep=clock.sleep))
    assert len(out) == len(short_run)
    assert np.array_equal(np.array([s.t for s in out]), short_run.t)
    assert np.array_equal(np.stack([s.theta for s in out]), short_run.theta)
    assert sum(clock.sleeps) == pytest.approx(short_run.t[-1] - short_run.t[0])


def test_realtime_stream_speed_and_loop(short_run):
    clock = FakeClock()
    stream = twin.iter_realtime(short_run, speed=4.0, loop=True, clock=clock, sleep=clock.sleep)
    out = [next(stream) for _ in range(3 * len(short_run))]
    times = np.array([s.t for s in out])
    assert np.all(np.diff(times) > 0)
    assert sum(clock.sleeps) == pytest.approx((times[-1] - times[0]) / 4.0)


def test_a_late_consumer_gets_every_sample_without_sleeping(short_run):
    clock = FakeClock()
    stream = twin.iter_realtime(short_run, clock=clock, sleep=clock.sleep)
    next(stream)
    clock.now += 1000.0
    rest = list(stream)
    assert len(rest) == len(short_run) - 1 and clock.sleeps == []


def test_replay_file_is_the_log(short_run, tmp_path):
    csv, _ = twin.write_log(short_run, tmp_path / "replay.csv")
    clock = FakeClock()
    replayed = list(twin.iter_realtime(read_log(csv), clock=clock, sleep=clock.sleep))
    assert np.allclose([s.theta for s in replayed], short_run.theta, rtol=1e-8, atol=1e-12)


@given(arrays(float, 20, elements=st.floats(-3.14, 3.14)), st.integers(0, 2**14 - 1))
def test_counts_are_what_the_encoder_reports(theta, zero):
    counts = twin.to_counts(theta, zero)
    assert counts.dtype == np.uint16 and np.all(counts < 2**14)
    back = P.count_delta(counts, zero)
    assert np.allclose(back * model.ENCODER_COUNT_RAD, theta, atol=model.ENCODER_COUNT_RAD / 2
                       + 1e-12)


def test_encoder_track_holds_each_sample_until_the_next(short_run):
    track = twin.EncoderTrack(short_run)
    t0 = short_run.t - short_run.t[0]
    assert np.array_equal(track.angles(t0), short_run.theta)
    assert np.array_equal(track.angles(t0[:-1] + 0.5 * np.diff(t0)), short_run.theta[:-1])
    assert np.array_equal(track.angles(np.array([1e6])), short_run.theta[-1:])
    looped = twin.EncoderTrack(short_run, loop=True)
    assert np.array_equal(looped.angles(t0 + looped.period), short_run.theta)


def test_the_twin_drives_the_simulated_device(short_run):
    """The firmware core behind the simulated device (delta6.sim.simdevice), sampling the
    twin's encoder angles, encodes exactly the twin's counts."""
    device = simdevice.SimulatedDevice(motion=twin.EncoderTrack(short_run), rate_hz=50)
    try:
        t_us = np.round((short_run.t - short_run.t[0]) * 1e6)
        assert np.array_equal(device.counts_at(t_us),
                              twin.to_counts(short_run.theta, device.mech_zero))
        assert device.advance(1.0) == 51 and device.samples_taken == 51
    finally:
        device.close()
