"""The MCAP log (ROS 2 messages): what it writes, decoded by the independent mcap_ros2 reader,
and what reads back through the common log reader; damaged files give one clear line."""
from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer as Ros2Writer

from delta6.link import ros2msg as R
from delta6.link.logfile import PARTIAL_SUFFIX, LogError, LogWriter, open_log_writer, read_log
from delta6.link.mcaplog import DIAGNOSTICS_PERIOD, McapLogWriter
from delta6.link.protocol import Status

values = st.one_of(st.floats(-1e9, 1e9), st.just(float("nan")))


def _log(path, n=1000, rate=250.0, theta_every=1, meta=None, seed=0):
    """A device-like log: angles on every ``theta_every``-th row, flagged rows, host times."""
    rng = np.random.default_rng(seed)
    t = 3.0 + np.arange(n) / rate
    theta = rng.normal(size=(n, 6)) * 0.05
    theta[np.arange(n) % theta_every != 0] = np.nan
    wrench = rng.normal(size=(n, 6)) * 5
    status = np.full(n, int(Status.TARE_ACTIVE))
    status[7] |= Status.OVERRANGE
    status[300] |= Status.WRENCH_INVALID | Status.ENCODER3
    wrench[300] = np.nan
    theta[300, 2] = np.nan
    meta = {"design": "delta6", "serial_number": "0x00000042", "host_clock_offset": "1.7e9",
            **(meta or {})}
    with open_log_writer(path, meta, optional=("seq", "status", "host_t")) as log:
        for start in range(0, n, 37):       # blocks as a live logger writes them
            part = slice(start, start + 37)
            log.write_block(t[part], theta[part], wrench[part], seq=np.arange(n)[part] + 100,
                            status=status[part], host_t=t[part] + 0.25)
    return t, theta, wrench, status


def _messages(path):
    with open(path, "rb") as f:
        out = {}
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for m in reader.iter_decoded_messages():
            out.setdefault(m.channel.topic, []).append(m)
        return out


def test_ros2_messages_decode_with_mcap_ros2(tmp_path):
    path = tmp_path / "run.mcap"
    t, theta, wrench, status = _log(path, theta_every=3, meta={"frame_id": "tool0"})
    msgs = _messages(path)
    n = len(t)
    assert [len(msgs[k]) for k in (R.TOPIC_WRENCH, R.TOPIC_JOINTS, R.TOPIC_SAMPLE)] == \
        [n, len(range(0, n, 3)), n]
    assert msgs[R.TOPIC_WRENCH][0].channel.message_encoding == "cdr"
    assert msgs[R.TOPIC_WRENCH][0].schema.name == R.WRENCH_STAMPED
    stamps = np.array([m.decoded_message.header.stamp.sec * 10**9 + m.decoded_message.header.stamp.nanosec
                       for m in msgs[R.TOPIC_WRENCH]])
    assert np.array_equal(stamps, np.round(t * 1e9).astype(np.int64))
    got = np.array([[w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
                    for w in (m.decoded_message.wrench for m in msgs[R.TOPIC_WRENCH])])
    assert np.array_equal(got, wrench, equal_nan=True)
    assert {m.decoded_message.header.frame_id for m in msgs[R.TOPIC_WRENCH]} == {"tool0"}
    joint = msgs[R.TOPIC_JOINTS][1].decoded_message
    assert joint.name == list(R.JOINT_NAMES) and joint.header.stamp.nanosec == \
        round(t[3] * 1e9) % 10**9
    assert np.array_equal(joint.position, theta[3])
    # Message log time is the host's receive time as UNIX time: host_t + host_clock_offset.
    assert msgs[R.TOPIC_WRENCH][5].message.log_time == round((t[5] + 0.25 + 1.7e9) * 1e9)
    sample = msgs[R.TOPIC_SAMPLE][10].decoded_message
    assert sample.layout.dim[0].label == "t,seq,status,host_t"
    assert sample.data == [t[10], 110.0, float(status[10]), t[10] + 0.25]


def test_diagnostics_once_per_second_with_every_flag_of_the_second(tmp_path):
    path = tmp_path / "run.mcap"
    t, *_, status = _log(path, n=1000)          # 4 s at 250 Hz
    diags = [m.decoded_message.status[0] for m in _messages(path)[R.TOPIC_STATUS]]
    assert len(diags) == int(np.ceil((t[-1] - t[0]) / DIAGNOSTICS_PERIOD))
    first, second = diags[0], diags[1]         # sample 7 overranges, sample 300 fails
    assert first.level == R.WARN and "overrange" in first.message
    assert dict((kv.key, kv.value) for kv in first.values)["flagged"] == "1"
    assert second.level == R.ERROR and "wrench_invalid" in second.message
    assert all(d.level == R.OK and d.message == "tare_active" for d in diags[2:])
    assert sum(int(dict((kv.key, kv.value) for kv in d.values)["samples"]) for d in diags) == 1000
    assert first.hardware_id == "delta6 0x00000042"


@given(st.integers(1, 30).flatmap(lambda n: st.tuples(
    arrays(float, (n, 6), elements=values), arrays(float, (n, 6), elements=values),
    st.lists(st.floats(1e-6, 10.0), min_size=n, max_size=n))),
    st.sampled_from([(), ("seq",), ("status", "temp_c"), ("seq", "status", "host_t", "temp_c")]),
    st.text(alphabet=st.characters(min_codepoint=33, max_codepoint=126), max_size=12))
def test_round_trip_through_read_log_is_exact(tmp_path_factory, data, optional, frame_id):
    theta, wrench, steps = data
    n = len(theta)
    t = 0.5 + np.cumsum(steps)
    columns = {c: np.arange(n) * 3.0 + i for i, c in enumerate(optional)}
    path = tmp_path_factory.mktemp("m") / "x.mcap"
    with McapLogWriter(path, {"frame_id": frame_id, "note": "a b"}, optional=optional) as log:
        log.write_block(t, theta, wrench, **columns)
    back = read_log(path, require_complete_rows=False)
    assert np.array_equal(back.t, t)
    assert np.array_equal(back.wrench, wrench, equal_nan=True)
    # A row without any angle has no JointState; it reads back as NaN like the CSV's blanks.
    assert np.array_equal(back.theta, theta, equal_nan=True)
    for c in ("seq", "status", "host_t", "temp_c"):
        assert (getattr(back, c) is None) == (c not in optional)
        if c in optional:
            assert np.array_equal(getattr(back, c), columns[c])
    assert back.meta == {"frame_id": frame_id, "note": "a b", "schema": "1"}


def test_time_steps_below_a_nanosecond_are_refused(tmp_path):
    with pytest.raises(LogError, match="at least 1 ns"):
        with McapLogWriter(tmp_path / "x.mcap") as log:
            log.write_block(np.array([1.0, 1.0 + 1e-10]), None, np.zeros((2, 6)))


def test_the_reader_goes_by_content_and_keeps_the_csv_checks(tmp_path):
    path = tmp_path / "looks-like.csv"
    with McapLogWriter(path) as log:
        log.write_block(np.array([1.0, 2.0]), np.zeros((2, 6)), np.full((2, 6), np.nan))
    assert len(read_log(path, require_complete_rows=False)) == 2
    with pytest.raises(LogError, match="missing or NaN Fx value at sample 1"):
        read_log(path)


def test_a_bag_written_by_another_tool_reads_through_the_generic_decoder(tmp_path):
    """Frame id, joint order and extra joints differ from ours: decoded message by message."""
    path = tmp_path / "other.mcap"
    with open(path, "wb") as f:
        w = Ros2Writer(f)
        ws = w.register_msgdef(R.WRENCH_STAMPED, R.definition(R.WRENCH_STAMPED))
        js = w.register_msgdef(R.JOINT_STATE, R.definition(R.JOINT_STATE))
        names = ["gripper"] + list(reversed(R.JOINT_NAMES))
        for i in range(5):
            header = {"stamp": {"sec": 100 + i, "nanosec": 5}, "frame_id": "world_long_name"}
            w.write_message(R.TOPIC_WRENCH, ws, {"header": header, "wrench": {
                "force": {"x": i, "y": 1.0, "z": 2.0}, "torque": {"x": 3.0, "y": 4.0, "z": 5.0}}})
            w.write_message(R.TOPIC_JOINTS, js, {"header": header, "name": names,
                                                 "position": [9.0] + [i + j / 10 for j in range(6)],
                                                 "velocity": [], "effort": []})
        w.finish()
    log = read_log(path)
    assert np.array_equal(log.t, 100 + np.arange(5) + 5e-9)
    assert np.array_equal(log.wrench[:, 0], np.arange(5))
    assert np.allclose(log.theta[2], [2.5, 2.4, 2.3, 2.2, 2.1, 2.0])
    assert log.seq is None and log.status is None


def test_blocks_reach_the_os_and_a_clean_close_renames(tmp_path):
    path = tmp_path / "run.mcap"
    partial = tmp_path / ("run.mcap" + PARTIAL_SUFFIX)
    log = McapLogWriter(path, flush_every=10_000)
    sizes = []
    for i in range(3):
        log.write_block(np.arange(5) * 0.01 + i, None, np.ones((5, 6)))
        sizes.append(partial.stat().st_size)
    assert sizes[0] < sizes[1] < sizes[2] and not path.exists()
    log.close()
    assert path.exists() and not partial.exists() and len(read_log(path, require_complete_rows=False)) == 15


def test_every_damaged_file_is_one_clear_error_or_a_log(tmp_path):
    path = tmp_path / "run.mcap"
    _log(path, n=400)
    data = path.read_bytes()
    rng = np.random.default_rng(1)
    outcomes = set()
    for trial in range(150):
        damaged = bytearray(data)
        if trial % 3 == 0:
            damaged = damaged[: rng.integers(8, len(data))]
        else:
            for at in rng.integers(8, len(data), size=rng.integers(1, 4)):
                damaged[at] ^= 1 << int(rng.integers(8))
        bad = tmp_path / "bad.mcap"
        bad.write_bytes(bytes(damaged))
        try:
            log = read_log(bad, require_complete_rows=False)
            assert len(log) > 0
            outcomes.add("log")
        except LogError as exc:
            assert "\n" not in str(exc) and str(bad) in str(exc)
            outcomes.add("error")
    assert "error" in outcomes


def test_csv_and_mcap_writers_share_one_interface(tmp_path):
    for name in ("a.csv", "a.mcap"):
        with open_log_writer(tmp_path / name, {"design": "delta6"}, optional=("status",)) as log:
            log.write(1.0, [0.1] * 6, None, status=3)
            log.write(2.0, None, [1.0] * 6, status=4)
        back = read_log(tmp_path / name, require_complete_rows=False)
        assert np.array_equal(back.status, [3, 4])
        assert np.isnan(back.wrench[0]).all() and np.isnan(back.theta[1]).all()
    assert isinstance(open_log_writer(tmp_path / "b.csv"), LogWriter)


def test_the_schema_text_names_every_dependency():
    text = R.definition(R.DIAGNOSTIC_ARRAY)
    assert text.count("MSG: ") == 4 and "diagnostic_msgs/KeyValue[] values" in text
    buf = io.BytesIO()
    w = Ros2Writer(buf)
    for datatype in (R.WRENCH_STAMPED, R.JOINT_STATE, R.FLOAT64_MULTI_ARRAY, R.DIAGNOSTIC_ARRAY):
        w.register_msgdef(datatype, R.definition(datatype))   # parses, or raises
    w.finish()


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**9), st.booleans())
@example(10**9, True)                   # the whole partial: every sample, none dropped
@example(10**9, False)
def test_a_killed_writers_partial_says_cut_row_dropped_only_when_one_was(tmp_path_factory, at,
                                                                          with_theta):
    """What SIGKILL leaves: the blocks that reached the OS, cut anywhere after the header.
    The metadata flags a dropped row exactly when a sample lost a message to the cut."""
    from delta6.link import mcaplog

    folder = tmp_path_factory.mktemp("kill")
    path, partial = folder / "run.mcap", folder / ("run.mcap" + PARTIAL_SUFFIX)
    log = McapLogWriter(path, {"source": "test"}, optional=("seq", "status"))
    for i in range(4):
        t = np.arange(20) * 0.004 + 0.08 * i
        log.write_block(t, np.zeros((20, 6)) if with_theta else None, np.ones((20, 6)),
                        seq=np.arange(20) + 20 * i, status=np.zeros(20, int))
    whole = partial.read_bytes()        # the writer killed here: no footer
    log.close()
    header = whole.index(b"delta6-log") + 200
    cut = whole[:header + min(at, len(whole) - header)]
    killed = folder / ("killed.mcap" + PARTIAL_SUFFIX)
    killed.write_bytes(cut)
    try:
        data = read_log(killed, require_complete_rows=False)
    except LogError:
        return                          # nothing whole before the cut: one line, fine
    _, topics, _ = mcaplog._records(killed, cut, cut_ok=True)
    wrench_messages = len(topics[R.TOPIC_WRENCH][1])
    assert ("cut_row_dropped" in data.meta) == (len(data.t) < wrench_messages)
    if len(cut) == len(whole):
        assert len(data.t) == 80 and "cut_row_dropped" not in data.meta
