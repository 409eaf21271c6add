"""``delta6 virtual``: the port on stdout, the other commands working against it unchanged, a
clean shutdown, and one-line errors with exit status 2."""
from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

from delta6.cli import main
from delta6.link.logfile import LogWriter
from delta6.sim import avrsim

from conftest import ROOT

pytestmark = pytest.mark.avr   # runs the virtual board (simavr)


def delta6(*args, **kwargs):
    return subprocess.run([sys.executable, "-m", "delta6", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, **kwargs)


@pytest.mark.slow
@pytest.mark.parametrize("motion, note", [([], "demo motion"),
                                           (["--twin", "ideal", "--twin-duration", "5"],
                                            "the digital twin, scenario ideal")])
def test_virtual_board_serves_the_host_commands(motion, note, tmp_path):
    stats = tmp_path / "stats.json"
    board = subprocess.Popen([sys.executable, "-m", "delta6", "virtual", "--speed", "0",
                              "--stats", str(stats), *motion], cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        port = board.stdout.readline().strip()
        assert port.startswith("/dev/")
        streamed = delta6("stream", "--port", port, "--duration", "1", "--interval", "0.2")
        assert streamed.returncode == 0, streamed.stderr
        assert "streaming 250 Hz" in streamed.stderr
        assert " 0 lost in 0 gaps" in streamed.stderr
        lines = [ln for ln in streamed.stdout.splitlines() if ln.startswith("t ")]
        assert len(lines) >= 3 and all(ln.endswith("ok") for ln in lines)
        assert len({ln.split("Fx")[1][:9] for ln in lines}) > 1     # the encoders move
        info = delta6("info", "--port", port, "--json")
        assert info.returncode == 0, info.stderr
        assert json.loads(info.stdout)["design_name"] == "delta6"
    finally:
        board.send_signal(signal.SIGTERM)
        _, err = board.communicate(timeout=30)
    assert board.returncode == 0, err
    assert note in err and "ran " in err and " 0 missed periods" in err
    report = json.loads(stats.read_text())
    assert report["timing"]["samples"] > 250 and report["link"]["clients"] == 2


def test_bad_replay_file_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("not a log\n")
    assert main(["virtual", "--replay", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "replay file" in err


def test_wrench_only_log_cannot_drive_the_encoders(tmp_path, capsys):
    log = tmp_path / "wrench_only.csv"
    with LogWriter(log, {"design": "delta6"}) as w:
        import numpy as np
        w.write_block(np.arange(3) * 0.01, np.full((3, 6), np.nan), np.zeros((3, 6)))
    assert main(["virtual", "--replay", str(log)]) == 2
    assert "no complete row of theta_e1..6" in capsys.readouterr().err


def test_a_log_of_another_design_cannot_drive_this_firmware(tmp_path, capsys):
    # Its angles come from another mechanism: the streamed wrench would be wrong.
    log = tmp_path / "stiff.csv"
    with LogWriter(log, {"design": "stiff", "design_hash": "0x487c4e16"}) as w:
        import numpy as np
        w.write_block(np.arange(3) * 0.01, np.zeros((3, 6)), np.zeros((3, 6)))
    assert main(["virtual", "--replay", str(log)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "recorded with design stiff" in err
    assert err.count("--design") == 1      # the fix is said once


@pytest.mark.parametrize("args, words", [
    (["--fault", "9:weak:0:1"], "encoder 9"),
    (["--fault", "1:loud:0:1"], "kind"),
    (["--zero", "1,2,3"], "--zero"),
    (["--loop"], "--loop goes with --replay"),
    # Files the board writes only when it ends are checked before it starts.
    (["--eeprom", "/nonexistent/dir/e.bin"], "--eeprom /nonexistent/dir/e.bin: the folder "
                                             "/nonexistent/dir does not exist"),
    (["--stats", "/nonexistent/x.json"], "--stats /nonexistent/x.json: the folder"),
    (["--stats", "/tmp/"], "is a folder"),
])
def test_bad_options_are_one_line_and_exit_2(args, words, capsys):
    assert main(["virtual", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and words in err


def test_missing_simavr_says_what_to_install(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(avrsim, "SIMAVR_HEADER", tmp_path / "nothing.h")
    assert main(["virtual", "--static"]) == 2
    assert "apt-get install" in capsys.readouterr().err


def test_an_outside_process_drives_the_board_through_live(tmp_path):
    import numpy as np

    from delta6.core.design import load
    from delta6.core.model import wrench as model_wrench
    from delta6.link import protocol as P
    from delta6.link.device import Device
    from delta6.sim.virtualboard import LiveChannel, theta_to_counts

    from conftest import DESIGNS

    sock = tmp_path / "live.sock"
    board = subprocess.Popen([sys.executable, "-m", "delta6", "virtual", "--static", "--speed",
                              "0", "--live", str(sock)], cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        port = board.stdout.readline().strip()
        live = LiveChannel(sock)
        with Device(port) as dev:
            dev.set_mode("raw")
            dev.start(100)
            assert np.all(dev.get(timeout=10).wrench == 0)          # at rest
            pose = np.array([0.1, 0.05, -0.08, 0.12, -0.06, 0.03])
            live.set_theta(None, pose)
            for _ in range(500):            # samples still on their way show the rest pose
                sample = dev.get(timeout=10)
                if np.array_equal(sample.counts, theta_to_counts(pose)):
                    break
            lsb = np.asarray(dev.info().lsb)
        live.close()
    finally:
        board.send_signal(signal.SIGTERM)
        _, err = board.communicate(timeout=30)
    assert board.returncode == 0, err
    assert np.array_equal(sample.counts, theta_to_counts(pose))
    ref = model_wrench(load(DESIGNS / "delta6.toml"), P.counts_to_theta(sample.counts, 0))
    assert np.all(np.abs(sample.wrench - ref) <= lsb / 2 + 1e-5) and np.abs(ref).max() > 1
