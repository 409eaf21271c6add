"""``delta6 stream`` for piping (CSV, JSON lines), as terminal plots, and served to Foxglove: a
WebSocket client decodes the ROS 2 messages the running command publishes."""
from __future__ import annotations

import asyncio
import io
import json
import subprocess
import sys
import time

import numpy as np
import pytest
import websockets
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory

from delta6.cli import main
from delta6.commands._termplot import MARK, RollingPlot
from delta6.link import ros2msg as R

URL = "delta6sim://?motion=sine"


def test_csv_on_stdout_has_every_sample_in_the_log_columns(capsys):
    assert main(["stream", "--port", URL, "--duration", "0.4", "--rate", "500", "--raw",
                 "--format", "csv"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == ("t,theta_e1,theta_e2,theta_e3,theta_e4,theta_e5,theta_e6,Fx,Fy,Fz,Mx,My,Mz,"
                        "seq,status,host_t")
    table = np.genfromtxt(io.StringIO("\n".join(lines[1:])), delimiter=",")
    assert table.shape[1] == 16 and len(table) > 100
    assert np.all(np.diff(table[:, 13]) == 1)                 # every sample, none skipped
    assert np.allclose(np.diff(table[:, 0]), 2e-3)
    assert np.isfinite(table[:, 1:13]).all()


def test_jsonl_is_one_object_per_sample(capsys):
    assert main(["stream", "--port", URL, "--duration", "0.3", "--rate", "250",
                 "--format", "jsonl"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(records) > 40 and [r["seq"] for r in records] == list(range(len(records)))
    assert set(records[0]) == {"t", "seq", "status", "flags", "wrench", "host_t"}
    assert len(records[0]["wrench"]) == 6 and all(isinstance(v, float) for v in records[0]["wrench"])


def test_plot_frames_show_six_panels(capsys):
    assert main(["stream", "--port", URL, "--duration", "0.6", "--rate", "250", "--plot",
                 "--interval", "0.2", "--plot-seconds", "0.5"]) == 0
    frames = [f for f in capsys.readouterr().out.split("\n\n") if f.strip()]
    assert len(frames) >= 2
    last = frames[-1].splitlines()
    assert [line.split()[0] for line in last if line[:2] in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")] == \
        ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
    assert last[-1].startswith("t ") and last[-1].endswith(" ok")


def test_plot_and_a_pipe_format_do_not_mix(capsys):
    assert main(["stream", "--port", URL, "--plot", "--format", "csv"]) == 2
    assert "--plot draws on the terminal" in capsys.readouterr().err


def test_rolling_plot_columns_follow_the_signal():
    plot = RollingPlot(seconds=1.0, width=10, height=4)
    t = np.arange(1000) / 1000.0
    wrench = np.zeros((1000, 6))
    wrench[500:, 0] = 2.0                     # a step in Fx half way
    wrench[:, 1] = np.nan                     # Fy never valid
    plot.add(t, wrench)
    lo, hi = plot.columns(0)
    assert np.array_equal(lo[:5], np.zeros(5)) and np.array_equal(hi[5:], np.full(5, 2.0))
    rows = plot.panel(0)[1:]
    assert rows[0] == "|" + " " * 5 + MARK * 5 + "|"          # top row: after the step
    assert rows[-1].startswith("|" + MARK * 5)                 # bottom row: before it
    assert plot.panel(1)[0].startswith("Fy        nan")
    assert all(MARK not in row for row in plot.panel(1)[1:])
    plot.add(t + 5.0, wrench)                 # the span rolls: old samples drop out
    assert plot._t.min() >= 5.0 and len(plot._t) == 1000


@pytest.mark.slow
def test_foxglove_client_receives_the_stream_at_its_rate(tmp_path):
    """The command serves while printing CSV; a WebSocket client subscribes to every topic, and
    what it decodes equals what the command printed, at the stream's rate."""
    rate, seconds = 250, 4.0
    proc = subprocess.Popen([sys.executable, "-m", "delta6", "stream", "--port", URL,
                             "--rate", str(rate), "--duration", str(seconds), "--format", "csv",
                             "--foxglove", "--foxglove-port", "0", "--frame-id", "sensor"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        assert line.startswith("Foxglove: open connection ws://127.0.0.1:"), line
        port = int(line.rsplit(":", 1)[1])
        received = asyncio.run(_receive(port, listen=2.0))
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "samples served to Foxglove" in err
    channels, messages, wall = received
    topics = {c["topic"]: c for c in channels.values()}
    assert set(topics) == set(R.TOPICS)
    assert all(c["encoding"] == "cdr" and c["schemaEncoding"] == "ros2msg" for c in topics.values())
    decoded = {}
    factory = DecoderFactory()
    for cid, payload in messages:
        c = channels[cid]
        schema = Schema(id=cid, name=c["schemaName"], encoding="ros2msg", data=c["schema"].encode())
        decoded.setdefault(c["topic"], []).append(factory.decoder_for("cdr", schema)(payload))
    wrenches = decoded[R.TOPIC_WRENCH]
    span = wall[-1] - wall[0]
    assert 0.8 * rate < (len(wrenches) - 1) / span < 1.2 * rate
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in wrenches])
    assert np.allclose(np.diff(stamps), 1 / rate)              # consecutive samples, none lost
    assert {m.header.frame_id for m in wrenches} == {"sensor"}
    printed = np.genfromtxt(io.StringIO(out), delimiter=",", names=True)
    at = np.searchsorted(printed["t"], stamps - 1e-7)
    assert np.allclose(printed["t"][at], stamps, atol=1e-9)
    got = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                     m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for m in wrenches])
    want = np.stack([printed[a] for a in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")], axis=1)[at]
    assert np.allclose(got, want, rtol=1e-8, atol=0)
    sample_t = np.array([m.data[0] for m in decoded[R.TOPIC_SAMPLE]])
    assert abs(len(sample_t) - len(wrenches)) <= 1             # the window may cut a row
    assert np.allclose(sample_t[:len(wrenches)], stamps[:len(sample_t)], atol=1e-9)
    assert R.TOPIC_JOINTS not in decoded                        # wrench-only stream: no angles
    assert decoded[R.TOPIC_STATUS][0].status[0].name == "delta6"


async def _receive(port: int, listen: float):
    channels, messages, wall = {}, [], []
    async with websockets.connect(f"ws://127.0.0.1:{port}",
                                  subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"]) as ws:
        deadline = time.monotonic() + listen
        while time.monotonic() < deadline:
            try:
                msg = await asyncio.wait_for(ws.recv(), timeout=max(0.01, deadline - time.monotonic()))
            except asyncio.TimeoutError:
                break
            if isinstance(msg, str):
                op = json.loads(msg)
                if op["op"] == "advertise":
                    subs = []
                    for c in op["channels"]:
                        channels[c["id"]] = c
                        subs.append({"id": c["id"], "channelId": c["id"]})
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            elif msg[0] == 1:                  # message data: op, subscription id, log time, payload
                sub = int.from_bytes(msg[1:5], "little")
                messages.append((sub, bytes(msg[13:])))
                if channels[sub]["topic"] == R.TOPIC_WRENCH:
                    wall.append(time.monotonic())
    return channels, messages, wall


@pytest.mark.parametrize("announced", [False, True])
def test_a_device_restart_while_streaming_is_reported(capsys, monkeypatch, announced):
    """The device's counters begin again (a restart whose BOOT event may be lost): stream
    says so on stderr, once per restart, and counts it in its summary, as log does."""
    import threading

    from serial import PortNotOpenError

    from delta6.commands import stream
    from delta6.link import protocol as P

    from support.scripted import Scripted

    stop = threading.Event()
    writers = []

    def records():      # 30 records, then the counters begin again until the end
        i = 0
        while not stop.wait(0.002):
            n = i if i < 30 else i - 30
            boot = P.encode_event(P.EventCode.BOOT, 0) if announced and i == 30 else b""
            try:
                device.loop_write(boot + P.encode_wrench(n, 1000 + 4000 * n, 0, (0,) * 6))
            except PortNotOpenError:
                return          # the command closed the port: its stream is over
            i += 1

    def answer(device, command, request_id):
        if command == P.Command.START:
            writers.append(threading.Thread(target=records, daemon=True))
            writers[-1].start()
        return device.normal(command, request_id)

    device = Scripted(answer)
    monkeypatch.setattr(stream, "open_device", lambda args, **kw: device.open())
    try:
        assert main(["stream", "--port", "scripted", "--duration", "0.5", "--format", "csv"]) == 0
    finally:
        stop.set()
        for writer in writers:
            writer.join(timeout=2.0)
    captured = capsys.readouterr()
    assert len(captured.out.strip().splitlines()) > 1 + 30
    # Counters that began again without a BOOT event may also be a host that fell behind:
    # only a restart the device confirmed is called one.
    said = "the device restarted: a new session" if announced else "the session broke ("
    assert captured.err.count(said) == 1 and captured.err.count("a new session") == 1
    assert captured.err.strip().splitlines()[-1].endswith(
        "the device restarted 1 time" if announced else "the session broke 1 time")


def test_the_rate_after_a_restart_counts_only_the_samples_after_it(capsys):
    """A restart inside a block: the rate window starts at the restart, not at the block's
    start (whose pre-restart times made the next rate 0)."""
    from delta6.commands.stream import _Sessions

    class Block:          # a block: times and sessions
        def __init__(self, t, session):
            self.t, self.session = t, session

        def __len__(self):
            return len(self.t)

    sessions = _Sessions()
    block = Block(t=np.arange(10) * 0.01, session=np.array([0] * 6 + [1] * 4))
    assert sessions.update(Block(t=block.t[:2], session=block.session[:2]), 0) is None
    assert sessions.update(block, 1) == 6
    assert (sessions.restarts, sessions.breaks) == (1, 0)
    later = Block(t=np.arange(3) * 0.01, session=np.array([1, 2, 2]))
    assert sessions.update(later, 1) == 1             # no new confirmation: a broken session
    assert (sessions.restarts, sessions.breaks) == (1, 1)
    assert sessions.summary() == ", the device restarted 1 time, the session broke 1 time"
