"""``delta6 log -o run.mcap`` and ``delta6 convert``: ROS 2 bags from the device, and CSV <->
MCAP without loss of the logged columns."""
from __future__ import annotations

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from delta6.cli import main
from delta6.link import ros2msg as R
from delta6.link.logfile import read_log


def _topics(path):
    counts = {}
    with open(path, "rb") as f:
        for schema, channel, message, decoded in make_reader(
                f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            counts.setdefault(channel.topic, []).append(decoded)
    return counts


def test_log_writes_a_ros2_bag_from_the_device(tmp_path, capsys):
    out = tmp_path / "run.mcap"
    assert main(["log", "--port", "delta6sim://?motion=sine", "-o", str(out), "--duration", "0.6",
                 "--rate", "500", "--raw", "--frame-id", "ft_sensor"]) == 0
    assert "0 of" in capsys.readouterr().err
    log = read_log(out)
    assert 200 < len(log) and np.all(np.diff(log.seq) == 1) and np.allclose(np.diff(log.t), 2e-3)
    assert log.meta["frame_id"] == "ft_sensor" and float(log.meta["host_clock_offset"]) > 1e9
    msgs = _topics(out)
    assert len(msgs[R.TOPIC_WRENCH]) == len(msgs[R.TOPIC_JOINTS]) == len(log)
    first = msgs[R.TOPIC_WRENCH][0]
    assert first.header.frame_id == "ft_sensor"
    assert first.header.stamp.sec * 10**9 + first.header.stamp.nanosec == round(log.t[0] * 1e9)
    assert np.array_equal(msgs[R.TOPIC_JOINTS][3].position, log.theta[3])
    assert 1 <= len(msgs[R.TOPIC_STATUS]) <= 2          # 0.6 s of samples: one or two reports


def test_convert_round_trips_a_csv_log_byte_for_byte(tmp_path, capsys):
    csv = tmp_path / "dev.csv"
    assert main(["log", "--port", "delta6sim://", "-o", str(csv), "--duration", "0.3",
                 "--rate", "250"]) == 0             # wrench only: the angle columns are empty
    sim = tmp_path / "sim.csv"
    assert main(["simulate", "--scenario", "paper", "--duration", "4", "--record-temp",
                 "-o", str(sim)]) == 0
    for source in (csv, sim):
        bag, back = tmp_path / (source.stem + ".mcap"), tmp_path / (source.stem + "-back.csv")
        assert main(["convert", str(source), str(bag)]) == 0
        assert main(["convert", str(bag), str(back)]) == 0
        assert back.read_text() == source.read_text()
    capsys.readouterr()


def test_convert_from_mcap_keeps_every_value_at_the_csv_precision(tmp_path, capsys):
    bag = tmp_path / "run.mcap"
    assert main(["log", "--port", "delta6sim://?motion=sine", "-o", str(bag), "--duration", "0.3",
                 "--rate", "250", "--raw"]) == 0
    csv, again = tmp_path / "run.csv", tmp_path / "again.mcap"
    assert main(["convert", str(bag), str(csv), "--frame-id", "other"]) == 0
    assert main(["convert", str(csv), str(again)]) == 0
    a, b = read_log(bag), read_log(again)
    assert np.array_equal(a.seq, b.seq) and np.array_equal(a.status, b.status)
    for name in ("t", "theta", "wrench", "host_t"):     # the CSV keeps 9 significant digits
        assert np.allclose(getattr(a, name), getattr(b, name), rtol=5e-9, atol=0), name
    assert b.meta["frame_id"] == "other"
    assert {k: v for k, v in a.meta.items() if k != "frame_id"} == \
        {k: v for k, v in b.meta.items() if k != "frame_id"}
    capsys.readouterr()


def test_convert_errors_are_one_line(tmp_path, capsys):
    assert main(["convert", str(tmp_path / "none.csv"), str(tmp_path / "x.mcap")]) == 2
    assert capsys.readouterr().err.strip().endswith("none.csv: no such file")
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + b"\x01" * 40)
    assert main(["convert", str(junk), str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "not a readable MCAP file" in err and err.count("\n") == 1
    same = tmp_path / "same.csv"
    same.write_text("x")
    assert main(["convert", str(same), str(same)]) == 2
    assert "would overwrite the log being read" in capsys.readouterr().err


def test_convert_never_replaces_a_log_without_force(tmp_path, capsys):
    run = tmp_path / "run.csv"
    assert main(["simulate", "--duration", "2", "-o", str(run)]) == 0
    other = tmp_path / "other.csv"
    other.write_text("a recording of its own\n")
    capsys.readouterr()
    assert main(["convert", str(run), str(other)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists" in err and "--force" in err
    assert other.read_text() == "a recording of its own\n"
    assert main(["convert", str(run), str(other), "--force"]) == 0
    assert len(read_log(other)) == len(read_log(run))
