"""The firmware's device state machine (delta6_device.cpp), driven natively with the clock in
the test's hands: commands, tare, configuration and EEPROM, faults, the status word, telemetry,
and the link model. What the board does, minus the board."""
from __future__ import annotations

import numpy as np
import pytest

from delta6.core.model import wrench as model_wrench
from delta6.link import protocol as P
from delta6.link.decoder import SequenceTracker, StreamDecoder
from delta6.sim.simdevice import Motion, NativeCore, SimulatedDevice

from conftest import ROOT

C = P.Command


class Bench:
    """A simulated device and a decoder on its output."""

    def __init__(self, **kwargs):
        self.sim = SimulatedDevice(**kwargs)
        self.decoder = StreamDecoder()
        self.request = 0
        self.boot = self.collect()

    def collect(self) -> list:
        return self.decoder.feed(self.sim.read())

    def send(self, command, *args, request=None, run=0.0) -> list:
        if request is None:
            request = self.request % 255 + 1
        self.request = request
        self.sim.write(P.encode_command(command, request, *args))
        if run:
            self.sim.advance(run)
        return self.collect()

    def run(self, seconds: float) -> list:
        self.sim.advance(seconds)
        return self.collect()

    def answer(self, records, request=None):
        """The answer to ``request`` (default: the last one sent) in ``records``; if it is
        not there yet, let the link drain for up to 50 ms (as time would pass on a board)."""
        request = self.request if request is None else request
        records = list(records)
        for _ in range(50):
            found = [r for r in records if isinstance(r, (P.Ack, P.Nack, P.Info, P.Telemetry))
                     and r.request_id == request]
            if found:
                break
            records += self.run(0.001)
        assert len(found) == 1, records
        return found[0]

    def lsb(self) -> np.ndarray:
        return self.answer(self.send(C.GET_INFO)).lsb


def data(records):
    return [r for r in records if isinstance(r, P.WrenchRecord)]


@pytest.fixture
def bench():
    b = Bench(rate_hz=500)
    yield b
    b.sim.close()


def test_boot_announces_itself_and_flags_the_erased_eeprom(bench):
    boot = bench.boot
    assert boot[0] == P.Event(P.EventCode.BOOT, 0)
    assert boot[1] == P.Event(P.EventCode.CONFIG_DEFAULTS, P.ConfigProblem.ERASED)
    info = boot[2]
    assert isinstance(info, P.Info) and info.request_id == 0
    assert info.design_name == "delta6" and info.design_hash == bench.sim.design.hash32()
    assert info.status & P.Status.CONFIG_DEFAULTS and not info.streaming
    assert info.lsb_mantissa == (1, 1, 1, 2, 2, 2) and info.lsb_exponent == (-3, -3, -3, -5, -5, -5)
    assert np.allclose(info.full_scale, bench.sim.full_scale, rtol=1e-6)


def test_start_stop_and_rate(bench):
    assert data(bench.run(0.1)) == []                       # nothing until started
    ack = bench.answer(bench.send(C.START, 1000))
    assert ack == P.Ack(bench.request, C.START, 1000)
    records = data(bench.run(0.5))
    assert 498 <= len(records) <= 501         # the new period starts after the old one
    assert np.all(np.diff([r.time_us for r in records]) == 1000)
    assert np.all(np.diff([r.seq for r in records]) == 1)
    assert bench.sim.core.rate_hz == 1000
    bench.answer(bench.send(C.STOP))
    assert data(bench.run(0.2)) == []
    ack = bench.answer(bench.send(C.START, 0, run=0.1))     # 0: the configured rate
    assert ack.value == 1000


def test_rates_the_board_or_link_cannot_carry_are_refused(bench):
    nack = bench.answer(bench.send(C.START, 2500))
    assert (nack.reason, nack.detail) == (P.NackReason.RATE_TOO_HIGH, 2000)
    raw = Bench(rate_hz=100, baud=115_200, max_rate_hz=2000)
    nack = raw.answer(raw.send(C.START, 500))
    assert (nack.reason, nack.detail) == (P.NackReason.LINK_TOO_SLOW, 414)
    raw.answer(raw.send(C.START, 400))
    nack = raw.answer(raw.send(C.SET_MODE, P.Mode.WRENCH_RAW))              # 37-byte records do not fit
    assert (nack.reason, nack.detail) == (P.NackReason.LINK_TOO_SLOW, 280)
    assert raw.sim.core.mode == P.Mode.WRENCH


def test_wrench_matches_the_reference_within_half_a_step(bench):
    bench.send(C.SET_MODE, P.Mode.WRENCH_RAW)
    bench.send(C.START, 500)
    lsb = bench.lsb()
    records = data(bench.run(1.0))
    counts = np.array([r.counts for r in records])
    theta = P.counts_to_theta(counts, bench.sim.core.zero_counts)
    expected = model_wrench(bench.sim.design, theta).astype(np.float32)
    got = np.array([r.wrench for r in records]) * lsb
    assert np.all(np.abs(got - expected) <= lsb / 2 * (1 + 1e-4))
    # The counts are what the plant's encoders read at the record's time.
    times = np.array([r.time_us for r in records])
    assert np.array_equal(counts, bench.sim.counts_at(times))


def test_tare_averages_on_the_device(bench):
    pose = np.array([0.1, -0.05, 0.08, 0.02, -0.03, 0.04])
    bench.sim.motion = Motion.static(pose)
    bench.send(C.START, 1000)
    lsb = bench.lsb()
    bench.run(0.05)
    records = bench.send(C.TARE, 200, run=0.25)
    busy = [r.status for r in data(records) if r.status & P.Status.TARE_BUSY]
    assert len(busy) >= 190
    ack = bench.answer(records)
    assert ack == P.Ack(bench.request, C.TARE, 200)
    info = bench.answer(bench.send(C.GET_INFO))
    theta = P.counts_to_theta(bench.sim.counts_at([0]), info.zero_counts)
    reference = model_wrench(bench.sim.design, theta)[0]
    assert np.allclose(info.tare, reference, rtol=1e-5, atol=1e-7)
    after = data(bench.run(0.1))
    assert all(r.status & P.Status.TARE_ACTIVE for r in after)
    assert np.all(np.abs(np.array([r.wrench for r in after])) <= 1)     # within one step
    bench.answer(bench.send(C.CLEAR_TARE))
    cleared = data(bench.run(0.05))
    assert not any(r.status & P.Status.TARE_ACTIVE for r in cleared)
    assert np.allclose(np.array(cleared[-1].wrench) * lsb, reference, atol=lsb)


def test_a_retried_request_is_answered_but_not_run_again(bench):
    bench.sim.motion = Motion.static(np.full(6, 0.05))
    bench.answer(bench.send(C.START, 1000))     # behind the boot records still draining
    first = bench.send(C.TARE, 50, request=77, run=0.01)
    assert [r for r in first if isinstance(r, P.Ack)] == []          # still averaging
    again = bench.send(C.TARE, 50, request=77, run=0.1)              # retry while averaging
    assert [r for r in again if isinstance(r, P.Ack)] == [P.Ack(77, C.TARE, 50)]
    tare = bench.sim.core.tare.copy()
    bench.sim.motion = Motion.static(np.full(6, -0.05))             # the load changes
    bench.run(0.05)
    third = bench.send(C.TARE, 50, request=77, run=0.1)              # retry after it finished
    assert [r for r in third if isinstance(r, P.Ack)] == [P.Ack(77, C.TARE, 50)]
    assert np.array_equal(bench.sim.core.tare, tare)                 # not averaged again


def test_tare_over_a_faulty_encoder_is_refused(bench):
    bench.sim.encoder_faults = {3: 0.5}
    bench.send(C.START, 500)
    nack = bench.answer(bench.send(C.TARE, 100, run=0.5))
    assert nack.reason == P.NackReason.FAULT_DURING_AVERAGING
    assert nack.detail & P.Status.ENCODER3 and nack.detail & P.Status.WRENCH_INVALID
    assert not bench.sim.core.status & P.Status.TARE_ACTIVE
    assert "flagged" in nack.text()


def test_busy_commands_wait_for_the_averaging(bench):
    bench.send(C.START, 200)
    bench.send(C.TARE, 100)
    for command, args in [(C.TARE, (5,)), (C.CLEAR_TARE, ()), (C.SAVE_CONFIG, ()),
                          (C.ZERO_HERE, (5,)), (C.SET_ZERO, (0,) * 6), (C.LOAD_DEFAULTS, ())]:
        nack = bench.answer(bench.send(command, *args))
        assert nack.reason == P.NackReason.BUSY, command
    assert bench.answer(bench.send(C.PING)).value == int(bench.sim.time_us)


def test_zero_here_takes_the_current_pose_as_zero(bench):
    pose = np.array([0.2, -0.1, 0.05, 0.1, -0.2, 0.15])
    bench.sim.motion = Motion.static(pose)
    bench.send(C.START, 500)
    ack = bench.answer(bench.send(C.ZERO_HERE, 20, run=0.1))
    assert ack.value == 20
    zero = bench.sim.core.zero_counts
    assert np.array_equal(zero, bench.sim.counts_at([0])[0])
    after = data(bench.run(0.05))
    assert all(r.wrench == (0,) * 6 for r in after)
    nack = bench.answer(bench.send(C.SET_ZERO, 1, 2, 3, 4, 5, 16384))
    assert nack.reason == P.NackReason.BAD_ARGUMENT and nack.detail == 16384
    nack = bench.answer(bench.send(C.SET_ZERO, 1, 40000, 3, 4, 5, 16384))
    assert nack.detail == 40000                          # the first count beyond the turn
    bench.answer(bench.send(C.SET_ZERO, 1, 2, 3, 4, 5, 6))
    assert bench.sim.core.zero_counts.tolist() == [1, 2, 3, 4, 5, 6]


def test_zero_here_averages_right_across_the_wrap_half_a_turn_from_the_old_zero():
    """A rest position half a turn from the current zero, read with a count of noise: the
    samples straddle +8191 / -8192 from the old zero, which averaged to about 0; against the
    first sample they average to the rest position."""
    count = 2 * np.pi / 16384
    rest = np.array([np.pi, -np.pi + 0.6 * count, 0.1, 0.0, 0.0, 0.0])
    b = Bench(rate_hz=500, motion=Motion(pose=rest, amplitude=np.array([1.6, 1.6, 0, 0, 0, 0]) * count,
                                         frequency=np.array([37.0, 23.0, 0, 0, 0, 0]),
                                         phase=np.zeros(6)))
    try:
        old = b.sim.core.zero_counts.copy()
        ack = b.answer(b.send(C.ZERO_HERE, 200, run=0.5))
        assert ack.value == 200
        new = b.sim.core.zero_counts.astype(int)
        seen = b.sim.counts_at(np.arange(0, 400_000, 2000)).astype(int)
        assert len(set(((seen[:, 0] - old[0]) % 16384).tolist()) & {8191, 8192, 8193}) >= 2
        expected = b.sim.counts_at([0])[0].astype(int)
        for j in range(6):
            off = (new[j] - expected[j] + 8192) % 16384 - 8192
            assert abs(off) <= 2, (j, new[j], expected[j])
    finally:
        b.sim.close()


def test_the_loop_time_window_of_a_stopped_board_keeps_its_mean_and_restarts_at_start():
    """Stopped, no periodic record closes the window: after more than 65,535 samples its mean
    is still the loop time (a 16-bit count wrapped and read 65535 us). START opens a window of
    its own: the first periodic record does not report the idle time's loop times."""
    b = Bench(rate_hz=500, loop_time_us=900)
    try:
        b.run(140.0)                                        # 70,000 samples, stopped
        t = b.answer(b.send(C.GET_TELEMETRY))
        assert t.loop_time_max_us == 900 == t.loop_time_mean_us
        b.sim.loop_time_us = 300
        b.run(300.0)                           # 150,000 samples at 300 us: the 900s fade
        t = b.answer(b.send(C.GET_TELEMETRY))  # (their weight halves every ~32,768 samples)
        assert t.loop_time_max_us == 900 and 300 < t.loop_time_mean_us < 340
        b.sim.loop_time_us = 600
        b.send(C.START, 500)
        periodic = [r for r in b.run(1.05) if isinstance(r, P.Telemetry) and r.request_id == 0]
        assert len(periodic) == 1
        assert periodic[0].loop_time_max_us == 600 == periodic[0].loop_time_mean_us
    finally:
        b.sim.close()


def test_configuration_survives_a_power_cycle_only_when_saved(bench):
    bench.sim.motion = Motion.static(np.full(6, 0.03))
    bench.send(C.SET_MODE, P.Mode.WRENCH_RAW)
    bench.send(C.START, 250)
    bench.send(C.TARE, 10, run=0.1)
    writes = bench.sim.core.eeprom_writes
    for command in (C.PING, C.STOP, C.CLEAR_TARE, C.GET_INFO):
        bench.send(command)
    assert bench.sim.core.eeprom_writes == writes == 0       # never on ordinary commands
    bench.send(C.TARE, 10, run=0.1)
    assert bench.answer(bench.send(C.SAVE_CONFIG)) == P.Ack(bench.request, C.SAVE_CONFIG, P.CONFIG_BLOB_SIZE)
    assert bench.sim.core.eeprom_writes == 1
    saved_tare = bench.sim.core.tare.copy()

    reborn = Bench(rate_hz=500, eeprom=bench.sim.core.eeprom)
    assert [r for r in reborn.boot if isinstance(r, P.Event)] == [P.Event(P.EventCode.BOOT, 0)]
    info = reborn.boot[-1]
    assert (info.rate_hz, info.mode) == (250, P.Mode.WRENCH_RAW)
    assert not info.status & P.Status.CONFIG_DEFAULTS and info.status & P.Status.TARE_ACTIVE
    assert np.array_equal(np.float32(info.tare), saved_tare)
    assert reborn.sim.core.rate_changes == 1 and reborn.sim.core.rate_hz == 250


def _flip(blob: bytes, field: str, mask: int) -> bytes:
    """``blob`` with one byte of a configuration field XORed with ``mask``."""
    at = P.CONFIG_LAYOUT.offsets[field]
    return blob[:at] + bytes([blob[at] ^ mask]) + blob[at + 1:]


@pytest.mark.parametrize("damage, reason", [
    (lambda b: _flip(b, "tare", 4), P.ConfigProblem.BAD_CRC),
    (lambda b: b"\xff" * 256, P.ConfigProblem.ERASED),
    (lambda b: _flip(b, "layout", 6), P.ConfigProblem.BAD_VERSION)])
def test_a_corrupt_eeprom_falls_back_to_defaults_and_says_so(bench, damage, reason):
    bench.send(C.START, 250)
    bench.send(C.SAVE_CONFIG)
    reborn = Bench(rate_hz=500, eeprom=damage(bench.sim.core.eeprom))
    assert P.Event(P.EventCode.CONFIG_DEFAULTS, reason) in reborn.boot
    info = reborn.boot[-1]
    assert info.status & P.Status.CONFIG_DEFAULTS and info.rate_hz == 500
    assert info.config_problem == reason                     # INFO says why, too
    reborn.answer(reborn.send(C.SAVE_CONFIG))                # saving clears the flag
    assert not reborn.sim.core.status & P.Status.CONFIG_DEFAULTS
    assert reborn.answer(reborn.send(C.GET_INFO)).config_problem == 0


def test_a_blob_from_another_design_keeps_zero_counts_but_not_the_tare(bench):
    bench.send(C.SET_ZERO, 10, 20, 30, 40, 50, 60)
    bench.send(C.START, 200)
    bench.send(C.TARE, 5, run=0.1)
    bench.send(C.SAVE_CONFIG)
    other = Bench(design=bench.sim.design.replace(k_nm_per_rad=[0.9] * 6),
                  eeprom=bench.sim.core.eeprom)
    info = other.boot[-1]
    assert info.zero_counts == (10, 20, 30, 40, 50, 60)
    assert info.tare == (0.0,) * 6 and not info.status & P.Status.TARE_ACTIVE
    assert not info.status & P.Status.CONFIG_DEFAULTS


def test_a_dead_eeprom_is_reported(bench):
    bench.sim.core.break_eeprom()
    nack = bench.answer(bench.send(C.SAVE_CONFIG))
    assert (nack.reason, nack.detail) == (P.NackReason.EEPROM_FAILED, 0)
    assert bench.sim.core.status & P.Status.CONFIG_DEFAULTS


def test_malformed_commands_get_reasons_and_loopback_gets_silence(bench):
    nack = bench.answer(bench.send(C.PING, request=9))
    assert isinstance(nack, P.Ack)
    bench.sim.write(P.frame(bytes([0x9F, 12])))
    assert bench.answer(bench.collect(), 12) == P.Nack(12, 0x9F, P.NackReason.UNKNOWN_COMMAND, 0)
    bench.sim.write(P.frame(bytes([C.START, 13, 1])))          # one argument byte short
    assert bench.answer(bench.collect(), 13) == P.Nack(13, C.START, P.NackReason.BAD_LENGTH,
                                                           P.COMMAND_SIZES[C.START])
    bench.sim.write(P.encode_command(C.SET_MODE, 14, max(P.Mode) + 1))
    assert bench.answer(bench.collect(), 14).reason == P.NackReason.BAD_ARGUMENT
    bench.sim.write(P.encode_command(C.TARE, 15, 0))
    assert bench.answer(bench.collect(), 15).reason == P.NackReason.BAD_ARGUMENT
    # The device's own records sent back to it (a loopback) are never answered.
    bench.sim.write(P.encode_wrench(1, 2, 3, (0,) * 6) + P.encode_ack(16, C.PING, 0))
    assert bench.collect() == []
    t = bench.answer(bench.send(C.GET_TELEMETRY))
    assert (t.rx_bad_frames, t.rx_crc_errors) == (4, 0)     # unknown, short, 2 looped back


def test_garbage_to_the_device_is_counted_and_streaming_goes_on(bench):
    bench.send(C.START, 500)
    rng = np.random.default_rng(3)
    bench.sim.write(rng.integers(1, 256, 100).astype(np.uint8).tobytes() + b"\x00")
    bench.sim.write(rng.integers(1, 256, 20).astype(np.uint8).tobytes() + b"\x00")
    records = data(bench.run(0.2))
    assert len(records) in (100, 101) and np.all(np.diff([r.seq for r in records]) == 1)
    t = bench.answer(bench.send(C.GET_TELEMETRY))
    assert t.rx_overflows == 1 and t.rx_crc_errors + t.rx_bad_frames == 1


def test_encoder_faults_flag_exactly_their_samples():
    # A transmit queue with room for the boot records (250 bytes with INFO) and the first
    # data records at once: this test is about faults, not about the link.
    b = Bench(rate_hz=500, encoder_faults={3: 0.3, 6: 0.1}, seed=4, tx_capacity=512)
    b.send(C.SET_MODE, P.Mode.WRENCH_RAW)
    b.send(C.START, 500)
    records = data(b.run(1.0))
    status = np.array([r.status for r in records])
    wrench = np.array([r.wrench for r in records])
    failed = (status & P.ENCODER_MASK) != 0
    assert 0.3 < failed.mean() < 0.5
    assert np.all(status[failed] & P.Status.WRENCH_INVALID)
    assert np.all(wrench[failed] == P.INVALID_VALUE)                 # never a made-up value
    assert not np.any(wrench[~failed] == P.INVALID_VALUE)
    assert not np.any(status & (P.Status.ENCODER1 | P.Status.ENCODER2 | P.Status.ENCODER4 |
                                P.Status.ENCODER5))
    t = b.answer(b.send(C.GET_TELEMETRY))
    assert t.samples == len(records)
    assert t.encoder_errors[2] == int(((status & P.Status.ENCODER3) != 0).sum())
    assert t.encoder_errors[5] == int(((status & P.Status.ENCODER6) != 0).sum())


def test_solver_failures_and_overruns_are_flagged_and_counted():
    b = Bench(rate_hz=500, solver_fail=0.2, overrun=0.1, seed=5)
    b.send(C.START, 500)
    records = data(b.run(1.0))
    status = np.array([r.status for r in records])
    solver = (status & P.Status.SOLVER_ERROR) != 0
    assert 0.1 < solver.mean() < 0.3
    assert np.all(status[solver] & P.Status.WRENCH_INVALID)
    assert 0.03 < ((status & P.Status.LOOP_OVERRUN) != 0).mean() < 0.2
    t = b.answer(b.send(C.GET_TELEMETRY))
    assert t.solver_errors >= solver.sum() and t.overruns >= ((status & P.Status.LOOP_OVERRUN) != 0).sum()


def test_overrange_and_joint_limit(bench):
    design = bench.sim.design
    pose = np.array([-0.5, -0.5, -0.5, 0.5, 0.5, 0.5])          # a large load
    bench.sim.motion = Motion.static(pose)
    bench.send(C.START, 500)
    bench.send(C.TARE, 10, run=0.1)
    bench.sim.motion = Motion.static(-pose)                       # the opposite load
    records = data(bench.run(0.1))
    assert all(r.status & P.Status.OVERRANGE for r in records)
    assert all(P.MAX_VALUE in map(abs, r.wrench) for r in records)
    assert not any(r.status & P.Status.JOINT_LIMIT for r in records)
    assert bench.answer(bench.send(C.GET_TELEMETRY)).status & P.Status.OVERRANGE
    bench.sim.motion = Motion.static([design.joint_limit_rad + 0.002, 0, 0, 0, 0, 0])
    records = data(bench.run(0.05))
    assert all(r.status & P.Status.JOINT_LIMIT for r in records)
    # Beyond the box the solver refuses the pose: no wrench, not an extrapolated one; the
    # protocol's status table says so.
    invalid = P.Status.SOLVER_ERROR | P.Status.WRENCH_INVALID
    assert all(r.status & invalid == invalid for r in records)
    row = next(line for line in (ROOT / "docs" / "protocol.md").read_text().splitlines()
               if line.startswith("| 7 | JOINT_LIMIT |"))
    assert "SOLVER_ERROR" in row and "WRENCH_INVALID" in row and "extrapolated" not in row


def test_answers_go_first_on_a_full_link_and_every_drop_is_a_counted_gap():
    """A transmit queue 8 bytes longer than the info frame at 1.6 kHz: the info record only
    fits into an empty queue, so data records give way until it went out. The host sees
    exactly the gaps the device counts, and the first record after each gap says so."""
    b = Bench(rate_hz=1000, tx_capacity=P.wire_bytes(P.RecordType.INFO) + 8, baud=500_000)
    records = b.send(C.START, 1600)
    infos = 0
    for _ in range(20):
        got = b.send(C.GET_INFO, run=0.01)
        infos += sum(isinstance(r, P.Info) and r.request_id == b.request for r in got)
        records += got
    records += b.run(0.05)
    t = b.answer(b.send(C.GET_TELEMETRY))
    assert infos == 20 and b.decoder.stats.errors == 0
    stream = data(records)
    tracker = SequenceTracker()
    after_gap = []
    for r in stream:
        before = tracker.lost
        tracker.update(r.seq, r.time_us)
        if tracker.lost > before:
            after_gap.append(r)
    # Drops before the first record received (the boot info waited too) leave no gap but
    # show in its sequence number, which counts from 0.
    assert t.tx_dropped > 0 and tracker.lost + stream[0].seq == t.tx_dropped
    if stream[0].seq:
        after_gap.insert(0, stream[0])
    assert all(r.status & P.Status.TX_OVERFLOW for r in after_gap)
    assert sum(bool(r.status & P.Status.TX_OVERFLOW) for r in stream) == len(after_gap)


def test_time_wraps_and_sequence_wraps_unwrap_cleanly():
    b = Bench(rate_hz=1000, start_us=2**32 - 300_000)
    b.send(C.START, 1000)
    records = data(b.run(0.6))
    tracker = SequenceTracker()
    times = [tracker.update(r.seq, r.time_us)[1] for r in records]
    assert np.all(np.diff(times) == 1000) and times[-1] > 2**32


def test_telemetry_once_a_second_while_streaming(bench):
    bench.sim.temperature_centi = 2345
    bench.send(C.START, 500)
    records = bench.run(3.05)
    periodic = [r for r in records if isinstance(r, P.Telemetry)]
    assert len(periodic) == 3 and all(r.request_id == 0 for r in periodic)
    assert periodic[-1].temperature_c == pytest.approx(23.45)
    assert periodic[-1].loop_time_max_us == 600 == periodic[-1].loop_time_mean_us
    assert np.all(np.diff([r.time_us for r in periodic]) == 1_000_000)
    bench.send(C.STOP)
    assert not [r for r in bench.run(2) if isinstance(r, P.Telemetry)]


def test_a_tare_that_overflows_float_is_refused(bench):
    bench.send(C.TARE, 2)
    core = bench.sim.core
    huge = np.full((2, 6), 3e38, dtype=np.float32)
    core.samples([1000, 2000], np.zeros((2, 6)), [0, 0], [1, 1], huge, [0, 0], [0, 0])
    nack = bench.answer(bench.collect())
    assert (nack.reason, nack.detail) == (P.NackReason.FAULT_DURING_AVERAGING, P.Status.OVERRANGE)
    assert not core.status & P.Status.TARE_ACTIVE


def test_joint_limit_flag_agrees_with_the_solver_at_a_whole_count_limit(baseline):
    """A joint box of exactly 1010 counts: the solver still solves at 1010 counts, so the
    device must not flag it; one count more is beyond the box. (The device once derived its
    own limit by float truncation and got 1009, as it did for about half of all whole-count
    limits.)"""
    limit = 1010
    b = Bench(design=baseline.replace(joint_limit_rad=limit * P.COUNT_RAD), rate_hz=500)
    try:
        b.send(C.START, 500)
        for counts, flagged in ((limit, False), (limit + 1, True)):
            b.sim.motion = Motion.static([counts * P.COUNT_RAD, 0, 0, 0, 0, 0])
            records = data(b.run(0.05))[2:]
            assert records and all(bool(r.status & P.Status.JOINT_LIMIT) == flagged
                                   for r in records), counts
    finally:
        b.sim.close()


def split_at_answer(records, request):
    """The data records before and after the answer to ``request`` in the stream."""
    at = next(i for i, r in enumerate(records) if isinstance(r, (P.Ack, P.Nack))
              and r.request_id == request)
    return data(records[:at]), data(records[at + 1:])


@pytest.mark.parametrize("command, args, changed", [
    (C.SET_MODE, (2,), lambda r: r.counts is not None),
    (C.TARE, (20,), lambda r: r.status & P.Status.TARE_ACTIVE),
    (C.START, (1000,), lambda r: True),
    (C.LOAD_DEFAULTS, (), lambda r: True),
])
def test_the_first_record_after_a_change_is_marked_and_follows_the_answer(command, args, changed):
    """Records before a command's answer predate it, records after it carry it, and the first
    of those carries STREAM_CHANGED (the records and the answers share one queue)."""
    bench = Bench(rate_hz=500)
    bench.sim.motion = Motion.static(np.full(6, 0.05))
    first = data(bench.send(C.START, 500, run=0.05))
    assert first[0].status & P.Status.STREAM_CHANGED                 # START itself
    assert not any(r.status & P.Status.STREAM_CHANGED for r in first[1:])
    records = bench.send(command, *args, run=0.2)
    before, after = split_at_answer(records, bench.request)
    assert not any(r.status & P.Status.STREAM_CHANGED for r in before)
    assert after[0].status & P.Status.STREAM_CHANGED and all(changed(r) for r in after)
    assert not any(r.status & P.Status.STREAM_CHANGED for r in after[1:])
    if command == C.SET_MODE:
        assert all(r.counts is None for r in before)
    if command == C.TARE:
        assert not any(r.status & P.Status.TARE_ACTIVE for r in before)
    # Commands that change nothing the records mean leave no mark.
    quiet = bench.send(C.PING, run=0.05) + bench.send(C.GET_INFO, run=0.05)
    assert not any(r.status & P.Status.STREAM_CHANGED for r in data(quiet))
    bench.sim.close()


def test_abort_ends_an_averaging_that_would_keep_the_device_busy(bench):
    bench.send(C.START, 500)
    bench.send(C.TARE, 65535, request=40, run=0.1)                  # 2 minutes at 500 Hz
    assert bench.answer(bench.send(C.TARE, 5)).reason == P.NackReason.BUSY
    records = bench.send(C.ABORT, request=41, run=0.01)
    assert bench.answer(records, request=40) == P.Nack(40, C.TARE, P.NackReason.ABORTED, 0)
    assert bench.answer(records, request=41) == P.Ack(41, C.ABORT, 1)
    assert "aborted" in P.Nack(40, C.TARE, P.NackReason.ABORTED, 0).text()
    assert not any(r.status & (P.Status.TARE_BUSY | P.Status.TARE_ACTIVE)
                   for r in data(bench.run(0.05)))
    assert bench.answer(bench.send(C.TARE, 5, run=0.05)).value == 5  # no longer busy
    assert bench.answer(bench.send(C.ABORT)) == P.Ack(bench.request, C.ABORT, 0)


def test_info_and_telemetry_carry_the_boot_id():
    bench = Bench(rate_hz=500, boot_id=0xBEEF)
    info = next(r for r in bench.boot if isinstance(r, P.Info))
    assert info.boot_id == 0xBEEF and info.protocol == P.VERSION
    assert bench.answer(bench.send(C.GET_TELEMETRY)).boot_id == 0xBEEF
    bench.sim.close()


def test_a_1_0_device_is_read_without_the_appended_fields():
    """A 1.0 device's INFO (128 bytes) and TELEMETRY (48) records parse with the boot id left
    unknown (None) and no calibration; a 1.0 host reads the 1.1 records by their known prefix.
    The offsets are docs/protocol.md's, written here by hand: INFO's boot id at 156, after the
    calibration hash (128) and name (132), then (1.2) the model's hash (158) and name (162),
    then (1.3) the pipeline's fields (186..227); TELEMETRY's at 48."""
    bench = Bench(rate_hz=500, boot_id=0x1234)
    bench.sim.write(P.encode_command(C.GET_INFO, 9) + P.encode_command(C.GET_TELEMETRY, 10))
    bench.sim.advance(0.02)                      # the answers leave at the baud rate
    raw = bench.sim.read()
    bench.sim.close()
    payloads = [P.unframe(f) for f in raw.split(b"\x00")[:-1]]
    info, telemetry = (P.parse_payload(p) for p in payloads)
    assert [len(p) for p in payloads] == [228, 50]
    assert payloads[0][158:186] == bytes(28) and info.model_hash == 0       # no model built in
    assert payloads[0][156:158] == (0x1234).to_bytes(2, "little")   # u16, little-endian
    assert payloads[1][48:50] == (0x1234).to_bytes(2, "little")
    assert payloads[0][128:132] == bytes(4) and info.calibration_hash == 0   # none built in
    old_info = P.parse_payload(payloads[0][:128])
    old_telemetry = P.parse_payload(payloads[1][:48])
    assert old_info == info._replace(**P.APPENDED_FIELDS[P.RecordType.INFO])
    assert old_telemetry == telemetry._replace(boot_id=None)
    assert P.encode_record(old_info, minor=0) == P.frame(payloads[0][:128])
    assert P.encode_record(old_telemetry) == P.frame(payloads[1][:48])
    with pytest.raises(P.ProtocolError):
        P.parse_payload(payloads[0][:127])


@pytest.mark.parametrize("name", ["", "d", "n" * 23, "long-design-name-" * 3])
def test_info_sent_in_pieces_is_the_python_encoders_frame(name):
    """The device sends INFO in pieces split at its name fields' last byte: whatever the name
    (empty, full, longer than the field), the bytes on the wire are exactly the frame the host's
    encoder makes of the record they decode to."""
    core = NativeCore(design_name=name, design_hash=0xA1B2C3D4,
                      full_scale=[15.0, 15.0, 25.0, 0.38, 0.33, 0.43], joint_limit_rad=0.5,
                      joint_limit_counts=1365, baud=500_000, max_rate_hz=2000,
                      default_rate_hz=500, zero_counts=[0] * 6, serial_number=0xD6000001,
                      tx_capacity=512)
    core.set_time(0)
    core.begin(0, 0x0102)
    core.set_time(100_000)                  # the boot records have left
    frames = [f + b"\x00" for f in core.read().split(b"\x00")[:-1]]
    core.close()
    info_frames = [f for f in frames if P.unframe(f[:-1])[0] == P.RecordType.INFO]
    assert len(info_frames) == 1
    info = P.parse_payload(P.unframe(info_frames[0][:-1]))
    assert info.design_name == name[:23] and info.boot_id == 0x0102
    assert P.encode_info(info) == info_frames[0]
