"""The virtual board end to end: the firmware's ATmega328P image in simavr, six emulated
encoders, the host library on the pty (docs/virtual-board.md).

Every test runs the real image unpaced (speed 0): board time, not wall time, is what the
firmware sees, so results do not depend on how busy the machine is.
"""
from __future__ import annotations

import math
import os
import random
import time

import numpy as np
import pytest

from delta6.core import lowpass, toolframe
from delta6.core.design import load
from delta6.core.model import wrench as model_wrench
from delta6.link import protocol as P
from delta6.link.device import Device
from delta6.sim.virtualboard import (
    EEPROM_SIZE,
    Fault,
    VirtualBoard,
    demo_trajectory,
    firmware,
    theta_to_counts,
    write_replay,
)

from conftest import DESIGNS
from support.vboard import F_CPU, drain, pair, read_reads, wait_board_time

ZERO = np.array([1200, 5400, 9800, 14100, 300, 16000])   # mechanism zero, wraps for joint 6
STATUS_QUIET = P.Status.TARE_ACTIVE | P.Status.CONFIG_DEFAULTS


@pytest.fixture(scope="module")
def image():
    return firmware()


@pytest.fixture(scope="module")
def design():
    return load(DESIGNS / "delta6.toml")


@pytest.fixture
def motion(tmp_path):
    """3 s of motion over most of the joint box, at 1 kHz, as raw counts with ZERO."""
    t, theta = demo_trajectory(duration_s=3.0, rate_hz=1000.0, amplitude=0.9)
    counts = theta_to_counts(theta, ZERO)
    return t, counts, write_replay(tmp_path / "motion.d6rp", t, counts)


def samples_as_arrays(samples):
    t_us = np.array([round(s.t * 1e6) for s in samples], dtype=np.int64)
    seq = np.array([s.seq for s in samples])
    status = np.array([s.status for s in samples])
    wrench = np.array([s.wrench for s in samples])
    counts = np.array([s.counts for s in samples])
    return t_us, seq, status, wrench, counts


def test_replayed_trajectory_streams_the_reference_wrench(image, design, motion, tmp_path):
    t, served, replay = motion
    reads_path = tmp_path / "reads.txt"
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, live=True,
                      read_log=reads_path) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.set_mode("raw")
            assert dev.start(250) == 250
            samples = drain(dev, dev.get(timeout=10).t + 2.0)
            dev.stop()
            info = dev.info()
            health = dev.health
        board.stop()
        stats = board.stats()
    t_us, seq, status, wrench, counts = samples_as_arrays(samples)

    # Every record, in order, at the configured period.
    assert health.samples_lost == 0 and health.sequence_gaps == 0
    assert np.all(np.diff(seq) == 1)
    # The timer keeps the period exactly; a sample's time stamp (micros(), 4 us steps, read in
    # the timer interrupt) may come a few us late when another interrupt was running.
    assert abs(t_us[-1] - t_us[0] - 4000 * (len(t_us) - 1)) <= 24
    assert np.all(np.abs(np.diff(t_us) - 4000) <= 24)
    assert np.all(status & ~STATUS_QUIET == 0), [hex(s) for s in set(status)]

    # Each sample carries exactly the counts the emulated encoders served at its latch ...
    reads = read_reads(reads_path)
    index = pair(t_us, reads, 4000)
    assert np.array_equal(counts, reads.counts[index])
    assert np.all(reads.complete[index] == 0x3F)
    # ... which are the replay's counts in force at that board time (sample and hold).
    read_t = reads.cycle[index] / F_CPU
    row = np.searchsorted(t, read_t, side="right") - 1
    assert np.array_equal(counts, served[row])

    # The wrench is the reference model's for those quantised angles, within quantisation.
    theta = P.counts_to_theta(counts, ZERO)
    ref = model_wrench(design, theta)
    lsb = np.asarray(info.lsb)
    fs = np.asarray(info.full_scale)
    assert np.all(np.abs(wrench - ref) <= lsb / 2 + 2e-6 * fs)
    assert np.ptp(ref, axis=0).min() > 50 * lsb.max()     # the motion moved every axis

    # The emulated bus was used within the sensor's timing, without contention.
    enc = stats["encoders"]
    assert sum(enc["violations"].values()) == 0 and enc["contention"] == 0
    assert enc["aborted"] == 0 and enc["bad_commands"] == 0
    assert stats["timing"]["missed_ticks"] == 0 and stats["timing"]["marker_errors"] == 0
    assert stats["timing"]["latency_cycles"]["max"] < 5e-3 * F_CPU


def test_injected_faults_flag_exactly_the_affected_samples(image, motion, tmp_path):
    _, _, replay = motion
    faults = [Fault(2, "weak", 0.60, 0.70), Fault(5, "noanswer", 0.80, 0.84),
              Fault(1, "biterror", 1.00, 1.02), Fault(3, "strong", 1.20, 1.25),
              Fault(4, "weak", 1.40, 1.45), Fault(6, "biterror", 1.42, 1.50)]
    reads_path = tmp_path / "reads.txt"
    # Paced at twice real time: the windows are in board time and the stream must start before
    # the first one (unpaced, a slow host could start it late).
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=2, live=True, faults=faults,
                      read_log=reads_path) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.set_mode("raw")
            dev.start(250)
            samples = drain(dev, 1.7)
            assert samples[0].t < 0.55, "the stream started after the first fault window"
            telemetry = dev.telemetry()
        board.stop()
    reads = read_reads(reads_path)
    t_us, seq, status, wrench, counts = samples_as_arrays(samples)
    index = pair(t_us, reads, 4000)
    expected = reads.fault_mask[index]

    assert np.all(np.diff(seq) == 1)
    assert np.array_equal(status & P.ENCODER_MASK, expected)
    invalid = (status & P.Status.WRENCH_INVALID) != 0
    assert np.array_equal(invalid, expected != 0)
    assert np.all(np.isnan(wrench[invalid])) and np.all(np.isfinite(wrench[~invalid]))
    flagged = (expected[:, None] >> np.arange(6)) & 1 == 1
    assert np.all(counts[flagged] == 0)                       # never a made-up angle
    assert np.array_equal(counts[~flagged], reads.counts[index][~flagged])
    for f in faults:                                          # every window hit some samples
        in_window = (reads.cycle[index] >= f.start * F_CPU) & (reads.cycle[index] < f.stop * F_CPU)
        assert in_window.sum() >= round((f.stop - f.start) * 250) - 1
        assert np.all(flagged[in_window, f.encoder - 1])
    # The device's per-encoder counters saw every faulty read, streamed or not.
    assert list(telemetry.encoder_errors) == list((reads.faults != 0).sum(axis=0))


def test_a_replayed_logs_failed_reads_fail_again_never_held(image, design, tmp_path):
    """A log with missing angles (its board's failed reads) replays them as encoders that do
    not answer: the board flags exactly those encoders and sends no angle, where it once
    held the previous angle and flagged nothing."""
    from delta6.link.logfile import LogWriter
    t, theta = demo_trajectory(duration_s=2.0, rate_hz=200.0)
    theta = theta.copy()
    gone = np.zeros(theta.shape, dtype=bool)
    gone[(t >= 0.8) & (t < 0.9), 1] = True          # joint 2 for 20 samples
    gone[np.argmin(np.abs(t - 1.3)), 4] = True      # joint 5 for one
    theta[gone] = np.nan
    log = tmp_path / "with_failed_reads.csv"
    with LogWriter(log, {"design": design.name}) as w:
        w.write_block(t, theta, np.zeros(theta.shape))
    with VirtualBoard(image=image, replay=log, zero=ZERO, speed=2) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.set_mode("raw")
            dev.start(200)
            samples = drain(dev, 1.6)
        board.stop()
    t_us, seq, status, wrench, counts = samples_as_arrays(samples)
    row = np.clip(np.searchsorted(t, t_us / 1e6 - 1e-4, side="right") - 1, 0, len(t) - 1)
    flagged = ((status[:, None] >> np.arange(6)) & 1) == 1
    # Every flag is on a joint the log lost (within a sample of its stretch), and the stretch
    # of joint 2 is flagged throughout.
    near = gone[row] | gone[np.clip(row - 1, 0, None)] | gone[np.clip(row + 1, None, len(t) - 1)]
    assert np.all(near[flagged])
    assert flagged[:, 1].sum() >= 18 and flagged[:, 4].sum() >= 1
    assert np.all(counts[flagged] == 0) and not flagged[:, [0, 2, 3, 5]].any()


def test_random_bytes_neither_hang_nor_reset_the_board(image, motion):
    _, _, replay = motion
    rng = random.Random(5)
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, live=True) as board:
        with Device(board.port) as dev:
            dev.start(250)
            before = dev.telemetry()
            garbage = bytes(rng.randrange(256) for _ in range(4000))
            for i in range(0, len(garbage), 200):
                dev._write(garbage[i:i + 200])
            t_after = board.live.time() + 0.5
            samples = drain(dev, t_after + 0.2)
            after = dev.telemetry()
            assert dev.info(refresh=True).streaming
            boots = [e for e in dev.events if e.code == P.EventCode.BOOT]
            health = dev.health
    assert len(boots) == 1                          # only the power-on boot
    assert health.samples_lost == 0
    assert samples[-1].t > t_after
    rejected = sum(getattr(after, k) - getattr(before, k)
                   for k in ("rx_crc_errors", "rx_bad_frames", "rx_overflows"))
    assert rejected >= 20                           # the garbage was seen and refused
    assert after.overruns == before.overruns
    assert after.samples > before.samples


def test_commands_while_streaming(image, design, tmp_path):
    pose = np.array([0.12, -0.08, 0.05, 0.10, -0.15, 0.07])
    replay = write_replay(tmp_path / "pose.d6rp", [0.0], theta_to_counts(pose)[None])
    with VirtualBoard(image=image, replay=replay, speed=0, live=True) as board:
        with Device(board.port) as dev:
            dev.set_mode("raw")
            dev.start(250)
            first = drain(dev, dev.get(timeout=10).t + 0.2)
            w0 = first[-1].wrench
            assert np.allclose(w0, model_wrench(design, P.counts_to_theta(first[-1].counts, 0)),
                               atol=np.asarray(dev.info().lsb))
            offsets = dev.tare(25)
            assert np.allclose(offsets, w0, atol=np.asarray(dev.info().lsb))
            # The board runs ahead of the host: drop what was queued before each answer.
            dev.flush()
            tared = drain(dev, dev.get(timeout=10).t + 0.2)
            assert all(np.all(s.wrench == 0) for s in tared[-20:])
            assert all(s.status & P.Status.TARE_ACTIVE for s in tared[-20:])

            assert dev.start(125) == 125                      # a new rate while streaming
            dev.flush()
            slow = drain(dev, dev.get(timeout=10).t + 0.5)
            dt = np.diff([round(s.t * 1e6) for s in slow[-40:]])
            assert np.all(np.abs(dt - 8000) <= 24)

            dev.set_mode("wrench")                            # and a new mode
            dev.flush()
            plain = drain(dev, dev.get(timeout=10).t + 0.2)
            assert plain[-1].counts is None
            info = dev.info(refresh=True)
            assert info.streaming and info.rate_hz == 125 and info.mode == P.Mode.WRENCH
            dev.clear_tare()
            dev.flush()
            back = drain(dev, dev.get(timeout=10).t + 0.2)
            assert np.array_equal(back[-1].wrench, w0)
            health = dev.health
    assert health.samples_lost == 0 and health.command_retries == 0


def _blob(image_path) -> bytes:
    return image_path.read_bytes()[:50]


def test_configuration_survives_a_restart_and_a_corrupt_one_falls_back(image, tmp_path):
    eeprom = tmp_path / "eeprom.bin"
    pose = np.array([0.05, 0.02, -0.04, 0.03, 0.01, -0.02])
    replay = write_replay(tmp_path / "pose.d6rp", [0.0], theta_to_counts(pose, ZERO)[None])
    # A new board: erased EEPROM, defaults, and it says why.
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, eeprom=eeprom) as board:
        with Device(board.port) as dev:
            assert dev.info().status & P.Status.CONFIG_DEFAULTS
            assert [e.arg for e in dev.events if e.code == P.EventCode.CONFIG_DEFAULTS] == [1]
            dev.set_zero(ZERO)
            dev.set_mode("raw")
            dev.start(200)
            dev.tare(10)
            dev.stop()
            dev.save_config()
            saved = dev.info(refresh=True)
            assert not saved.status & P.Status.CONFIG_DEFAULTS
    assert eeprom.stat().st_size == EEPROM_SIZE
    # The same EEPROM image: the configuration is back.
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, eeprom=eeprom) as board:
        with Device(board.port) as dev:
            info = dev.info()
            assert not [e for e in dev.events if e.code == P.EventCode.CONFIG_DEFAULTS]
    assert info.rate_hz == 200 and info.mode == P.Mode.WRENCH_RAW
    assert tuple(info.zero_counts) == tuple(ZERO)
    assert info.tare == saved.tare and any(info.tare)
    assert info.status & P.Status.TARE_ACTIVE and not info.status & P.Status.CONFIG_DEFAULTS
    # One byte of the blob changed: defaults again, CRC mismatch (2) reported.
    data = bytearray(eeprom.read_bytes())
    data[20] ^= 0x5A
    eeprom.write_bytes(bytes(data))
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, eeprom=eeprom) as board:
        with Device(board.port) as dev:
            info = dev.info()
            reasons = [e.arg for e in dev.events if e.code == P.EventCode.CONFIG_DEFAULTS]
            dev.start()
            sample = dev.get(timeout=10)
    assert reasons == [2]
    assert info.status & P.Status.CONFIG_DEFAULTS and info.rate_hz == 250
    assert tuple(info.zero_counts) == (0,) * 6 and not any(info.tare)
    assert sample.status & P.Status.CONFIG_DEFAULTS


def test_an_eeprom_image_that_cannot_be_saved_fails_the_run(image, tmp_path):
    """A configuration the firmware saved and acknowledged must not vanish silently."""
    folder = tmp_path / "gone"
    folder.mkdir()
    board = VirtualBoard(image=image, speed=0, eeprom=folder / "e.bin").start()
    try:
        with Device(board.port) as dev:
            dev.tare(5)
            dev.save_config()
        folder.rmdir()                       # the folder went away while the board ran
        status = board.stop()
    finally:
        board.close()
    assert status == 2
    assert "error: could not save the EEPROM image" in board.stderr


def test_the_emulator_dies_with_the_program_that_started_it(tmp_path):
    """SIGKILL of the program that runs the board: the emulator notices and ends (it used to
    run on at half a core, its encoders frozen, its stream still saying ok)."""
    import signal
    import subprocess
    import sys
    script = ("from delta6.sim.virtualboard import VirtualBoard\n"
              "import time\n"
              "board = VirtualBoard(speed=1, wait_for_client=False).start()\n"
              "print(board.proc.pid, flush=True)\n"
              "time.sleep(60)\n")
    # The killed program cannot remove its temporary directory (the emulator writes its
    # statistics there as it ends): keep it under tmp_path, not in the system's /tmp.
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                              env=env)
    try:
        emulator = int(parent.stdout.readline())
        assert _alive(emulator)
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        deadline = time.monotonic() + 5
        while _alive(emulator) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(emulator)
    finally:
        if parent.poll() is None:
            parent.kill()


def _alive(pid: int) -> bool:
    """Whether pid runs (a zombie, dead but not yet reaped by init, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_watchdog_resets_a_hung_loop(tmp_path):
    image = firmware(test_hooks=True)
    with VirtualBoard(image=image, speed=0, live=True) as board:
        with Device(board.port) as dev:
            first_boot = [e.arg for e in dev.events if e.code == P.EventCode.BOOT]
            first_id = dev.info().boot_id
            dev.start(250)
            drain(dev, dev.get(timeout=10).t + 0.1)
            hung_at = board.live.time()
            board.live.hang(True)
            wait_board_time(board.live, hung_at + 0.4)
            board.live.hang(False)
            wait_board_time(board.live, hung_at + 0.7)
            info = dev.info(refresh=True)      # answered after everything before it arrived
            boots = [e.arg for e in dev.events if e.code == P.EventCode.BOOT]
            resets = dev.health.device_resets
        board.stop()
        stats = board.stats()
    assert first_boot == [0x01]                               # power-on
    assert len(boots) >= 2 and all(arg == 0x08 for arg in boots[1:])   # watchdog
    assert resets == len(boots) and stats["timing"]["boots"] == len(boots)
    assert not info.streaming                                 # a fresh start, not streaming
    # The boot id survives a reset in RAM and steps: the restart is known without BOOT.
    assert first_id is not None and info.boot_id == (first_id + len(boots) - 1) % 65536


def test_late_data_is_caught_by_the_sensor_timing(image, motion):
    # A sensor whose data settles 4 us after the falling edge: the firmware (which waits at
    # least 1 us plus its bit shuffling) samples stale bits; every read must then be refused.
    _, _, replay = motion
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0,
                      bus_timing_ns=(1000, 2000, 4000)) as board:
        with Device(board.port) as dev:
            dev.start(250)
            samples = drain(dev, dev.get(timeout=10).t + 0.2)
        board.stop()
        stats = board.stats()
    assert all(s.status & P.ENCODER_MASK == 0x3F for s in samples)
    assert all(np.all(np.isnan(s.wrench)) for s in samples)
    assert stats["encoders"]["violations"]["data_valid"] > 0


def test_fault_spec_parsing():
    assert Fault.parse("3:weak:1.0:1.5") == Fault(3, "weak", 1.0, 1.5)
    assert Fault.parse("6:noanswer:0:inf").stop == math.inf
    for bad in ("7:weak:0:1", "1:loud:0:1", "1:weak:2:1", "1:weak:0", "x:weak:0:1"):
        with pytest.raises(Exception) as err:
            Fault.parse(bad)
        assert "fault" in str(err.value)


def test_the_twin_drives_the_board_through_the_live_channel(image, design, tmp_path):
    from delta6 import twin
    run = twin.simulate(design, twin.scenario_effects("paper", 3), 3.0, 1000.0, 3)
    reads_path = tmp_path / "reads.txt"
    # Paced (twice real time) so that the updates, sent ahead of time, always lead the board.
    with VirtualBoard(image=image, zero=ZERO, speed=2, live=True, read_log=reads_path) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.set_mode("raw")
            dev.start(250)
            t0 = board.live.time() + 0.3
            sent = board.live.drive(twin.iter_realtime(run, speed=1000.0), t0=t0, lead=0.3)
            assert sent == len(run)
            samples = drain(dev, t0 + 2.5)
            lsb = np.asarray(dev.info().lsb)
        board.stop()
    reads = read_reads(reads_path)
    t_us, _, status, wrench, counts = samples_as_arrays(samples)
    index = pair(t_us, reads, 4000)
    latch = reads.cycle[index] / F_CPU
    driven = latch >= t0 + 0.002
    assert driven.sum() > 500
    # Each sample latched the twin's angles due at that board time (zero-order hold) ...
    row = np.searchsorted(run.t - run.t[0] + t0, latch[driven], side="right") - 1
    assert np.array_equal(counts[driven], theta_to_counts(run.theta[row], ZERO))
    # ... and the firmware's wrench is the analytical model's for them: the twin's truth
    # differs from it by the effects of the scenario, which is what the twin is for.
    ok = (status[driven] & P.Status.WRENCH_INVALID) == 0
    assert ok.mean() > 0.9
    ref = model_wrench(design, P.counts_to_theta(counts[driven][ok], ZERO))
    assert np.all(np.abs(wrench[driven][ok] - ref) <= lsb / 2 + 1e-5)


def test_overruns_are_counted_and_flagged_never_stretching_the_period(motion, tmp_path):
    # 500 Hz is beyond what the board sustains (docs/virtual-board.md); this build accepts it.
    image = firmware(defines=["DELTA6_MAX_RATE_HZ=2000"])
    _, _, replay = motion
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, live=True) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.start(500)
            dev.flush()
            before = dev.telemetry()
            samples = drain(dev, dev.get(timeout=10).t + 1.0)
            after = dev.telemetry()
            dev.stop()                                  # an overloaded board still answers
            health = dev.health
        board.stop()
        stats = board.stats()
    t_us, seq, status, _, _ = samples_as_arrays(samples)
    assert health.samples_lost == 0 and np.all(np.diff(seq) == 1)
    periods = np.diff(t_us) / 2000.0
    whole = np.rint(periods)
    assert np.all(np.abs(periods - whole) * 2000 <= 24)      # the period is never stretched
    lost = whole - 1
    assert lost.sum() > 20                                   # it really was overloaded
    flagged = (status[1:] & P.Status.LOOP_OVERRUN) != 0
    assert np.array_equal(flagged, lost > 0)                 # flagged exactly after a loss
    assert after.overruns - before.overruns >= flagged.sum()
    assert stats["timing"]["missed_ticks"] >= lost.sum()


def test_bus_contention_is_detected(motion):
    # A test build that releases the data line after the sensor starts driving it.
    image = firmware(defines=["DELTA6_TEST_LATE_RELEASE"])
    _, _, replay = motion
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.start(250)
            samples = drain(dev, dev.get(timeout=10).t + 0.2)
        board.stop()
        stats = board.stats()
    assert stats["encoders"]["contention"] >= 6 * len(samples)
    assert all(s.status & P.ENCODER_MASK == 0 for s in samples)   # the bits still arrive


def test_filter_tool_frame_and_limits_on_the_board(image, design, motion):
    """The pipeline as the AVR image runs it: a 20 Hz low-pass and a tool frame a centimetre
    up and turned 90 degrees about z, against the reference model filtered and moved by the
    Python references; OVERRANGE exactly on the samples over the Fz limit (or clipped)."""
    _, _, replay = motion
    with VirtualBoard(image=image, replay=replay, zero=ZERO, speed=0, live=True) as board:
        with Device(board.port) as dev:
            dev.set_zero(ZERO)
            dev.set_mode("raw")
            dev.set_filter(20)
            dev.set_tool((0.0, 0.0, 0.01), (0.0, 0.0, math.pi / 2))
            dev.set_limits([None, None, 5.0, None, None, None])
            dev.start(250)
            samples = drain(dev, dev.get(timeout=10).t + 1.2)
            info = dev.info()
            health = dev.health
    _, seq, status, wrench, counts = samples_as_arrays(samples)
    assert health.samples_lost == 0 and np.all(np.diff(seq) == 1)
    assert (info.filter_hz, info.limits[2]) == (20.0, round(5.0 / info.lsb[2]))
    ref = model_wrench(design, P.counts_to_theta(counts, ZERO)).astype(np.float32)
    filtered = lowpass.run(ref, *lowpass.design(20, 250))
    want = toolframe.to_tool(filtered, (0.0, 0.0, 0.01), (0.0, 0.0, math.pi / 2))
    lsb, fs = np.asarray(info.lsb), np.asarray(info.full_scale)
    settled = slice(60, None)      # the reference filter starts at the first sample received
    assert np.all(np.abs(wrench[settled] - want[settled]) <= 1.5 * lsb + 4e-6 * fs.max())
    fz_counts = np.round(wrench[:, 2] / lsb[2])
    over = (status & P.Status.OVERRANGE) != 0
    at_range = (np.abs(np.round(wrench / lsb)) >= P.MAX_VALUE).any(axis=1)
    assert over.any() and (~over).any()
    assert np.array_equal(over[~at_range], (np.abs(fz_counts) > info.limits[2])[~at_range])
