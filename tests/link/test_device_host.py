"""The host's Device class against the simulated device (the firmware's own protocol core in
process, through the delta6sim:// serial URL), and over pyserial's loop:// and socket://."""
from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest
import serial

from delta6.core.model import wrench as model_wrench
from delta6.link import protocol as P
from delta6.link.device import CommandRejected, CommandTimeout, Device, DeviceError, PortLost, SampleTimeout
from delta6.sim.simdevice import SimulatedDevice

POSE = "0.1,-0.05,0.08,0.02,-0.03,0.04"


def take(dev: Device, n: int, timeout: float = 2.0) -> list:
    it = dev.samples(timeout)
    return [next(it) for _ in range(n)]


def test_start_stop_rate_and_sample_fields():
    with Device("delta6sim://?rate=200") as dev:
        assert dev.info().rate_hz == 200 and not dev.info().streaming
        assert dev.start(1000) == 1000 and dev.info().streaming
        samples = take(dev, 300)
        t = np.array([s.t for s in samples])
        assert np.allclose(np.diff(t), 1e-3)
        assert np.all(np.diff([s.seq for s in samples]) == 1)
        assert np.all(np.diff([s.host_t for s in samples]) >= 0)
        assert all(s.valid and np.isfinite(s.wrench).all() and s.theta is None for s in samples)
        # The first record after START carries the mark of a changed stream; none after it.
        assert samples[0].flags == P.Status.CONFIG_DEFAULTS | P.Status.STREAM_CHANGED
        assert all(s.flags == P.Status.CONFIG_DEFAULTS for s in samples[1:])
        dev.stop()
        time.sleep(0.05)
        dev.flush()
        with pytest.raises(SampleTimeout, match="no sample from delta6sim://"):
            dev.get(timeout=0.1)
        assert dev.health.sequence_gaps == 0


def test_raw_mode_gives_angles_and_the_reference_wrench():
    with Device("delta6sim://") as dev:
        dev.set_mode("raw")
        dev.start(500)
        samples = take(dev, 200)
        lsb = dev.info().lsb
        design = dev._serial.simulation.design
    theta = np.array([s.theta for s in samples])
    counts = np.array([s.counts for s in samples])
    assert np.array_equal(P.counts_to_theta(counts, dev.info().zero_counts), theta)
    wrench = np.array([s.wrench for s in samples])
    expected = model_wrench(design, theta).astype(np.float32)
    assert np.all(np.abs(wrench - expected) <= lsb / 2 * (1 + 1e-4))


def test_commands_are_answered_while_streaming_without_losing_samples():
    """At a pace the link's spare 10 % carries (a burst of info records faster than that
    makes data records give way, counted as gaps: the next test). 500 Hz: at 1 kHz a 232-byte
    INFO frame and the next answer no longer fit the 256-byte transmit queue together with
    the data records (docs/protocol.md section 4)."""
    with Device("delta6sim://") as dev:
        dev.start(500)
        for _ in range(10):
            time.sleep(0.02)
            rtt, device_us = dev.ping()
            assert 0 < rtt < 0.5 and device_us > 0
            assert dev.info(refresh=True).streaming
            assert dev.telemetry().samples > 0
        take(dev, 50)
        h = dev.health
    assert h.sequence_gaps == 0 and h.decoder.errors == 0 and h.commands == 32


def test_tare_is_averaged_on_the_device():
    with Device(f"delta6sim://?motion=static&pose={POSE}") as dev:
        dev.start(1000)
        design = dev._serial.simulation.design
        before = take(dev, 5)[-1].wrench
        offsets = dev.tare(100)
        assert np.allclose(offsets, before, atol=dev.info().lsb)
        dev.flush()
        after = take(dev, 20)
        assert all(s.flags & P.Status.TARE_ACTIVE for s in after)
        assert np.all(np.abs([s.wrench for s in after]) <= dev.info().lsb)
        dev.clear_tare()
        dev.flush()
        cleared = take(dev, 5)[-1]
        assert np.allclose(cleared.wrench, before, atol=dev.info().lsb)
        assert np.allclose(offsets, model_wrench(design, np.array(
            [float(v) for v in POSE.split(",")])), atol=0.02)


def test_configuration_persists_in_the_eeprom_across_power_cycles(tmp_path):
    eeprom = tmp_path / "eeprom.bin"
    url = f"delta6sim://?eeprom={eeprom}&motion=static&pose={POSE}"
    with Device(url) as dev:
        assert dev.info().status & P.Status.CONFIG_DEFAULTS
        dev.set_mode("raw")
        dev.start(300)
        dev.tare(30)
        dev.save_config()
        assert not dev.info().status & P.Status.CONFIG_DEFAULTS
    with Device(url) as dev:
        info = dev.info()
        assert (info.rate_hz, info.mode) == (300, P.Mode.WRENCH_RAW)
        assert info.status & P.Status.TARE_ACTIVE and not info.status & P.Status.CONFIG_DEFAULTS
    blob = bytearray(eeprom.read_bytes())
    blob[P.CONFIG_LAYOUT.offsets["tare"] + 2] ^= 0x10          # a bit of a tare offset
    eeprom.write_bytes(bytes(blob))
    with Device(url) as dev:
        dev.start()                     # any command; the boot records went out before
        info = dev.info(refresh=True)
        assert info.status & P.Status.CONFIG_DEFAULTS and info.rate_hz == 200


def test_zero_here_takes_the_resting_pose_as_zero_and_clears_the_tare():
    with Device(f"delta6sim://?motion=static&pose={POSE}") as dev:
        dev.set_mode("raw")
        dev.start(500)
        dev.tare(10)
        resting = take(dev, 5)[-1].counts
        assert np.abs(take(dev, 1)[0].theta).max() > 0.01          # deflected from zero
        zero = dev.zero_here(50)
        assert zero == dev.info().zero_counts == tuple(resting)
        assert not dev.info().status & P.Status.TARE_ACTIVE
        dev.flush()
        after = take(dev, 20)
        assert all(np.array_equal(s.theta, np.zeros(6)) for s in after)
        assert not any(s.flags & P.Status.TARE_ACTIVE for s in after)
        for bad in (0, 70000):
            with pytest.raises(DeviceError, match="zero capture takes 1..65535 samples"):
                dev.zero_here(bad)


def test_load_defaults_restores_the_factory_configuration_in_ram_only(tmp_path):
    eeprom = tmp_path / "eeprom.bin"
    url = f"delta6sim://?rate=200&eeprom={eeprom}&motion=static&pose={POSE}"
    with Device(url) as dev:
        factory = dev.info()
        dev.set_mode("raw")
        dev.start(300)
        dev.tare(10)
        dev.set_zero([100, 200, 300, 400, 500, 600])
        dev.save_config()
        dev.load_defaults()
        info = dev.info()
        assert (info.rate_hz, info.mode, info.zero_counts, info.tare) == (
            factory.rate_hz, factory.mode, factory.zero_counts, (0.0,) * 6)
        assert not info.status & P.Status.TARE_ACTIVE
        dev.flush()
        later = take(dev, 3)[1:]                # wrench-only records at the factory rate
        assert later[0].theta is None and later[1].t - later[0].t == pytest.approx(1 / 200)
    with Device(url) as dev:                 # the saved configuration is still what boots
        info = dev.info()
        assert (info.rate_hz, info.zero_counts) == (300, (100, 200, 300, 400, 500, 600))


def test_a_vanishing_port_ends_iteration_with_a_clear_error_after_the_last_sample():
    with Device("delta6sim://?vanish_after=0.4") as dev:
        dev.start(500)
        got = []
        with pytest.raises(PortLost, match=r"lost the device on delta6sim://\?vanish_after=0.4: "
                                           r"device disconnected"):
            for sample in dev.samples(timeout=2.0):
                got.append(sample)
        assert 100 < len(got) <= 210
        assert len(got) == dev.health.samples
        assert np.all(np.diff([s.seq for s in got]) == 1)
        with pytest.raises(PortLost):
            dev.ping()


def test_sequence_gaps_match_what_the_device_dropped():
    # A transmit queue just larger than the INFO frame, as small as the device allows.
    capacity = P.wire_bytes(P.RecordType.INFO) + 8
    with Device(f"delta6sim://?tx_capacity={capacity}") as dev:
        dev.start(1600)
        for _ in range(15):
            dev.info(refresh=True)       # INFO answers push data records out of the way
        first = take(dev, 1)[0].seq
        time.sleep(0.05)
        dropped = dev.telemetry().tx_dropped
        time.sleep(0.05)
        h = dev.health
    assert dropped > 0
    assert h.samples_lost + first == dropped


def test_callbacks_latest_and_queue_drops():
    seen = []
    with Device("delta6sim://", queue_size=10) as dev:
        remove = dev.on_sample(seen.append)
        dev.start(1000)
        time.sleep(0.3)
        latest = dev.latest()
        remove()
        h = dev.health
        n = len(seen)
        time.sleep(0.05)
        assert len(seen) == n                                 # removed
    assert h.queue_drops > 200 and n >= h.samples - 1
    assert latest.seq >= seen[-1].seq - 1 and latest.seq > 150
    assert np.all(np.diff([s.seq for s in seen]) == 1)


def test_a_callback_may_not_send_commands():
    with Device("delta6sim://") as dev:
        dev.on_sample(lambda s: dev.ping())
        dev.start(500)
        take(dev, 20)
        assert dev.health.callback_errors >= 10
        assert isinstance(dev.callback_error, RuntimeError)


def test_wrong_baud_rate_gives_a_clear_timeout():
    t0 = time.monotonic()
    with pytest.raises(CommandTimeout, match=r"get info: no answer from delta6sim:// in 3 tries "
                                             r"of 0.1 s \(is a Delta6 connected at this baud"):
        Device("delta6sim://", baud=115_200, timeout=0.1).open()
    assert time.monotonic() - t0 < 1.0


def test_rejections_name_the_reason():
    with Device("delta6sim://?max_rate=1500") as dev:
        with pytest.raises(CommandRejected, match="start rejected by the device: rate above the "
                                                  "board's maximum of 1500 Hz"):
            dev.start(1501)
        with pytest.raises(DeviceError, match="mode is 'wrench' or 'raw'"):
            dev.set_mode("fast")
    with Device("delta6sim://?baud=115200", baud=115_200) as dev:
        with pytest.raises(CommandRejected, match="link carries at most 414 Hz"):
            dev.start(1000)


def test_a_device_can_be_reopened():
    dev = Device("delta6sim://")
    for _ in range(2):
        with dev:
            dev.start(500)
            assert len(take(dev, 10)) == 10
        assert repr(dev) == "Device('delta6sim://', closed)"


def test_unopenable_port_and_idle_stream():
    with pytest.raises(DeviceError, match="cannot open /dev/delta6-no-such-port"):
        Device("/dev/delta6-no-such-port").open()
    with Device("delta6sim://") as dev:
        with pytest.raises(SampleTimeout, match="is the stream started"):
            dev.get(timeout=0.1)


def test_device_time_unwraps_across_the_32_bit_wrap():
    with Device(f"delta6sim://?start_us={2**32 - 200_000}") as dev:
        dev.start(1000)
        t = np.array([s.t for s in take(dev, 400)])
    assert np.allclose(np.diff(t), 1e-3) and t[-1] > 2**32 * 1e-6


def test_replayed_frames_over_loop_url():
    """loop:// hands back what is written: recorded frames replayed through it decode, with
    the gap in them counted; a command gets no answer (its own echo is not one)."""
    sim = SimulatedDevice(rate_hz=500)
    info = P.parse_payload(P.unframe(sim.read().split(b"\x00")[2]))
    frames = [P.encode_info(info)]
    frames += [P.encode_wrench(seq, 1000 * seq, 0, (seq, -seq, 0, 0, 0, 5)) for seq in range(30)
               if seq != 12]
    with Device("loop://", handshake=False, timeout=0.1, retries=0) as dev:
        dev._serial.write(b"".join(frames))
        samples = take(dev, 29)
        assert [s.seq for s in samples] == [s for s in range(30) if s != 12]
        assert np.allclose(samples[3].wrench, [3e-3, -3e-3, 0, 0, 0, 1e-4])
        h = dev.health
        assert (h.sequence_gaps, h.samples_lost) == (1, 1)
        with pytest.raises(CommandTimeout):
            dev.ping()
        assert dev.health.decoder.unknown_types == 1           # our own ping, echoed
    sim.close()


def serve_once(url: str) -> tuple[int, threading.Thread]:
    """A TCP server that bridges one connection to a serial URL (like ser2net)."""
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]

    def bridge():
        conn, _ = server.accept()
        conn.settimeout(0.01)
        ser = serial.serial_for_url(url, baudrate=500_000, timeout=0.005)
        try:
            while True:
                try:
                    data = conn.recv(4096)
                    if not data:
                        break
                    ser.write(data)
                except socket.timeout:
                    pass
                out = ser.read(ser.in_waiting or 1)
                if out:
                    conn.sendall(out)
        except OSError:
            pass
        finally:
            ser.close()
            conn.close()
            server.close()

    thread = threading.Thread(target=bridge, daemon=True)
    thread.start()
    return port, thread


def test_device_over_socket_url():
    import delta6.link.device  # noqa: F401  (registers delta6sim:// for the bridge)
    port, thread = serve_once("delta6sim://?rate=250")
    with Device(f"socket://127.0.0.1:{port}") as dev:
        assert dev.info().design_name == "delta6"
        dev.start(500)
        samples = take(dev, 100)
        assert np.all(np.diff([s.seq for s in samples]) == 1)
    thread.join(timeout=2)
    assert not thread.is_alive()


def test_a_port_in_use_is_refused_as_busy():
    """A second program on the same port would take half of the bytes: refused at open."""
    import os
    master, slave = os.openpty()
    path = os.ttyname(slave)
    try:
        with Device(path, handshake=False):
            with pytest.raises(DeviceError) as info:
                Device(path, handshake=False).open()
            assert str(info.value) == (f"port busy: {path} is open in another program "
                                       "(another delta6 log or stream?)")
        with Device(path, handshake=False):     # free again once the first one closed
            pass
    finally:
        os.close(master)
        os.close(slave)


def test_a_capture_is_never_appended_to(tmp_path):
    capture = tmp_path / "old.bin"
    capture.write_bytes(b"an earlier session")
    with pytest.raises(DeviceError, match="the capture .*old.bin exists: a capture holds one "
                                          "session"):
        Device("delta6sim://", capture=capture).open()
    assert capture.read_bytes() == b"an earlier session"
    fresh = tmp_path / "new.bin"
    with Device("delta6sim://", capture=fresh) as dev:
        dev.start(500)
        take(dev, 20)
    assert fresh.stat().st_size > 20 * 25


def test_times_are_the_nearest_double_to_the_microsecond():
    """t = 14000 us is 0.014 s, not 0.013999999999999999."""
    sim = SimulatedDevice(rate_hz=500)
    info = P.parse_payload(P.unframe(sim.read().split(b"\x00")[2]))
    sim.close()
    frames = [P.encode_info(info)] + [P.encode_wrench(k, 14_000 * k, 0, (0,) * 6)
                                      for k in range(1, 4)]
    with Device("loop://", handshake=False, timeout=0.1, retries=0) as dev:
        dev._serial.write(b"".join(frames))
        samples = take(dev, 3)
    assert [repr(s.t) for s in samples] == ["0.014", "0.028", "0.042"]


def test_an_unusable_info_record_is_never_used_for_scaling():
    """An info record with a scale the protocol does not allow (mantissa 3) or of another major
    version: the samples wait for a usable one instead of being scaled with it."""
    from delta6.link.infocheck import info_problem
    sim = SimulatedDevice(rate_hz=500)
    info = P.parse_payload(P.unframe(sim.read().split(b"\x00")[2]))
    sim.close()
    assert info_problem(info) is None
    bad_scale = info._replace(lsb_mantissa=(3, 1, 1, 2, 2, 2))
    newer = info._replace(protocol=(2, 0))
    assert "axis 1 has a wrench step of 3e-3" in info_problem(bad_scale)
    assert info_problem(newer) == "protocol 2.0; this delta6 reads 1.x: update the host"
    assert "zero count" in info_problem(info._replace(zero_counts=(16384, 0, 0, 0, 0, 0)))
    assert "finite" in info_problem(info._replace(tare=(float("nan"),) * 6))
    with Device("loop://", handshake=False, timeout=0.1, retries=0) as dev:
        dev._serial.write(P.encode_info(bad_scale) + P.encode_wrench(1, 1000, 0, (1,) * 6))
        with pytest.raises(DeviceError, match="no device info"):
            take(dev, 1)


def test_no_sample_older_than_a_command_is_handed_out_after_it():
    """After tare() returns, every sample is tared; after set_mode('raw'), every sample has
    angles: the samples queued before the answer are dropped (counted), not handed out."""
    with Device("delta6sim://?motion=static&pose=0.1,0,0,0,0.05,0") as dev:
        dev.start(1000)
        time.sleep(0.2)                          # untared samples pile up in the queue
        dev.tare(20)
        after = take(dev, 50)
        assert all(s.status & P.Status.TARE_ACTIVE for s in after)
        assert after[0].status & P.Status.STREAM_CHANGED
        assert dev.latest().status & P.Status.TARE_ACTIVE
        time.sleep(0.1)
        dev.set_mode("raw")
        raw = take(dev, 50)
        assert all(s.counts is not None for s in raw) and raw[0].status & P.Status.STREAM_CHANGED
        assert dev.health.stale_dropped >= 100


def test_an_interrupted_tare_is_aborted_on_the_device():
    """Ctrl-C in a long tare: the device is told to stop averaging, and is not left busy."""
    import os
    import signal
    # Python's own Ctrl-C handler, whatever pytest was started with (a background job starts
    # with SIGINT ignored, and the signal would then never arrive).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with Device("delta6sim://?rate=500") as dev:
            dev.start(500)
            timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))   # a real Ctrl-C
            timer.start()
            with pytest.raises(KeyboardInterrupt):
                dev.tare(65535)                   # would take over two minutes
            assert not dev.info(refresh=True).status & P.Status.TARE_BUSY
            assert dev.abort() is False           # nothing left to abort
            assert np.all(np.isfinite(dev.tare(5)))   # and it takes commands again
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_new_boot_id_starts_a_new_session_even_with_counters_that_fit():
    """A restart whose BOOT event was lost and whose counters happen to continue: the boot id
    of the next INFO or TELEMETRY record tells the sessions apart."""
    sim = SimulatedDevice(rate_hz=500)
    info = P.parse_payload(P.unframe(sim.read().split(b"\x00")[2]))._replace(boot_id=7)
    telemetry = P.parse_payload(P.unframe(P.encode_record(P.Telemetry(
        0, 0, 0, 0, 0, (0,) * 6, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, boot_id=8))[:-1]))
    sim.close()

    def records(first):
        return b"".join(P.encode_wrench(k, 2000 * k, 0, (k,) * 6) for k in range(first, first + 10))

    stream = P.encode_info(info) + records(0) + P.encode_record(telemetry) + records(10)
    with Device("loop://", handshake=False, timeout=0.1, retries=0) as dev:
        dev._serial.write(stream)
        samples = take(dev, 20)
        assert [s.session for s in samples] == [0] * 10 + [1] * 10
        assert dev.health.restarts == 1 and dev.health.samples_lost == 0
    from delta6.link.bulkdecode import decode_capture
    cap = decode_capture(stream)
    assert [s.stop - s.start for s in cap.sessions] == [10, 10]
    same = stream.replace(P.encode_record(telemetry), P.encode_record(telemetry._replace(boot_id=7)))
    assert len(decode_capture(same).sessions) == 1


def test_a_1_0_device_has_no_abort():
    sim = SimulatedDevice(rate_hz=500)
    info = P.parse_payload(P.unframe(sim.read().split(b"\x00")[2]))
    sim.close()
    old = info._replace(protocol=(1, 0), boot_id=None)
    with Device("loop://", handshake=False, timeout=0.1, retries=0) as dev:
        dev._serial.write(P.encode_record(old, minor=0))     # 128 bytes, as 1.0 sent it
        deadline = time.monotonic() + 2
        while dev._info is None and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(DeviceError, match="protocol 1.0, which has no abort command"):
            dev.abort()
