"""The device subcommands end to end against the simulated device, and ``delta6 decode``."""
from __future__ import annotations

import numpy as np
import pytest

from delta6.cli import main
from delta6.core.model import wrench as model_wrench
from delta6.link import protocol as P
from delta6.link.device import Device
from delta6.link.logfile import read_log
from delta6.sim.simdevice import SimulatedDevice

from support.streams import make_frames


def capture_from_sim(seconds=0.5, raw=True, **kwargs) -> tuple[bytes, SimulatedDevice]:
    sim = SimulatedDevice(**kwargs)
    sim.write(P.encode_command(P.Command.SET_MODE, 1, P.Mode.WRENCH_RAW if raw else P.Mode.WRENCH))
    sim.write(P.encode_command(P.Command.START, 2, 500))
    sim.advance(seconds)
    return sim.read(), sim


def test_decode_turns_a_capture_into_the_documented_csv(tmp_path, capsys):
    data, sim = capture_from_sim(zero_counts=(10, 20, 30, 16380, 5, 8000))
    cap_file = tmp_path / "capture.bin"
    cap_file.write_bytes(b"\x13\x37" + data[:5000] + b"\x42" + data[5000:])    # damaged
    out = tmp_path / "run.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "1 missing in 1 gaps, 1 damaged frames" in err
    log = read_log(out)
    header = out.read_text().splitlines()
    assert header[0] == "# delta6-log schema=1"
    assert header[[h.startswith("t,") for h in header].index(True)] == \
        "t,theta_e1,theta_e2,theta_e3,theta_e4,theta_e5,theta_e6,Fx,Fy,Fz,Mx,My,Mz,seq,status"
    assert log.meta["design"] == "delta6" and log.meta["design_hash"] == "0x535534af"
    assert log.meta["mode"] == "wrench_raw" and log.meta["lsb"] == "0.001 0.001 0.001 2e-05 2e-05 2e-05"
    assert len(log) == 250 and np.allclose(np.diff(log.t)[:10], 2e-3)     # 251 sent, 1 hit
    # Angles are the plant's angles to within a count; the wrench is the model's at them.
    truth = sim.true_angles(log.t * 1e6)
    assert np.all(np.abs(log.theta - truth) <= P.COUNT_RAD / 2 + 1e-12)
    assert np.allclose(log.wrench, model_wrench(sim.design, log.theta),
                       atol=np.array([5e-4] * 3 + [1e-5] * 3) + 1e-9)
    assert (log.status == P.Status.CONFIG_DEFAULTS).all()


def test_decode_of_a_wrench_only_capture_leaves_angles_empty(tmp_path):
    data, _ = capture_from_sim(raw=False)
    cap_file = tmp_path / "c.bin"
    cap_file.write_bytes(data)
    out = tmp_path / "w.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 0
    log = read_log(out, require_complete_rows=False)
    assert np.isnan(log.theta).all() and np.isfinite(log.wrench).all()
    assert ",,,,,," in out.read_text().splitlines()[-1]


def test_decode_without_info_needs_the_design(tmp_path, capsys, root):
    frames, records = make_frames(50, seed=3, data_only=True)
    cap_file = tmp_path / "noinfo.bin"
    cap_file.write_bytes(b"".join(frames))
    out = tmp_path / "x.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 2
    assert "holds no device-info record, so the wrench scale is unknown: pass --design" in \
        capsys.readouterr().err
    assert main(["decode", str(cap_file), "-o", str(out), "--design",
                 str(root / "designs" / "delta6.toml")]) == 0
    log = read_log(out, require_complete_rows=False)
    valid = [r for r in records if not r.status & P.Status.WRENCH_INVALID]
    assert len(log) == 50
    w = np.array([r.wrench for r in records], float) * ([1e-3] * 3 + [2e-5] * 3)
    mask = np.array([not r.status & P.Status.WRENCH_INVALID for r in records])
    assert np.allclose(log.wrench[mask], w[mask]) and len(valid) == mask.sum()
    assert np.isnan(log.wrench[~mask]).all()


def test_decode_errors_are_one_line(tmp_path, capsys, root):
    out = str(tmp_path / "x.csv")
    assert main(["decode", str(tmp_path / "missing.bin"), "-o", out]) == 2
    assert "missing.bin: no such file" in capsys.readouterr().err
    junk = tmp_path / "junk.bin"
    junk.write_bytes(bytes(range(1, 200)) * 10)
    assert main(["decode", str(junk), "-o", out]) == 2
    assert "no data records in 1990 bytes" in capsys.readouterr().err
    data, _ = capture_from_sim(0.05)
    good = tmp_path / "good.bin"
    good.write_bytes(data)
    assert main(["decode", str(good), "-o", out, "--design",
                 str(root / "designs" / "stiff.toml")]) == 2
    err = capsys.readouterr().err
    assert "recorded from design hash 0x535534af, but" in err and err.count("\n") == 1


def test_log_records_a_clean_file_with_statistics(tmp_path, capsys):
    out = tmp_path / "log.csv"
    capture = tmp_path / "log.bin"
    assert main(["log", "--port", "delta6sim://", "-o", str(out), "--duration", "0.5",
                 "--rate", "1000", "--raw", "--capture", str(capture)]) == 0
    err = capsys.readouterr().err
    assert "0 of" in err and "missing (0 %) in 0 gaps" in err
    log = read_log(out)
    assert 400 < len(log) < 700
    assert np.allclose(np.diff(log.t), 1e-3) and np.all(np.diff(log.seq) == 1)
    assert np.all(np.diff(log.host_t) >= 0)
    assert log.meta["rate_hz"] == "1000" and log.meta["source"] == "delta6 log --port delta6sim://"
    assert not (tmp_path / "log.csv.partial").exists()
    # The raw capture decodes to the same samples, plus those that arrived after the log was
    # closed and before the stop command took effect.
    again = tmp_path / "again.csv"
    assert main(["decode", str(capture), "-o", str(again)]) == 0
    back = read_log(again)
    n = len(log)
    assert len(back) >= n
    assert np.array_equal(back.wrench[:n], log.wrench) and np.array_equal(back.theta[:n], log.theta)


def test_log_keeps_everything_when_the_port_vanishes(tmp_path, capsys):
    out = tmp_path / "cut.csv"
    status = main(["log", "--port", "delta6sim://?vanish_after=0.4", "-o", str(out),
                   "--duration", "5", "--rate", "500"])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2
    assert err[-1].startswith("delta6 log: error: lost the device on delta6sim://?vanish_after=0.4: "
                              "device disconnected")
    log = read_log(out, require_complete_rows=False)        # wrench only: no angles
    assert err[-1].endswith(f"{out} keeps the {len(log)} samples received before")
    assert 100 < len(log) <= 210 and np.all(np.diff(log.seq) == 1)


def test_ctrl_c_closes_the_log_cleanly(tmp_path, capsys, monkeypatch):
    calls = {"n": 0}
    original = Device.read_block

    def interrupted(self, *a, **kw):
        calls["n"] += 1
        if calls["n"] == 5:
            raise KeyboardInterrupt
        return original(self, *a, **kw)

    monkeypatch.setattr(Device, "read_block", interrupted)
    out = tmp_path / "int.csv"
    assert main(["log", "--port", "delta6sim://", "-o", str(out), "--rate", "500"]) == 0
    assert "(interrupted)" in capsys.readouterr().err
    assert out.exists() and len(read_log(out, require_complete_rows=False)) > 0


def test_info_tare_and_stream(capsys, tmp_path):
    url = "delta6sim://?motion=static&pose=0.1,0,0,0,0,0.1"
    assert main(["info", "--port", url]) == 0
    out = capsys.readouterr().out
    assert "design 'delta6' (hash 0x535534af)" in out and "Fz        25.1 N" in out
    assert "link at 500000 baud carries 1800 Hz wrench, 1216 Hz wrench+raw" in out
    assert main(["info", "--port", url, "--json"]) == 0
    assert '"design_name": "delta6"' in capsys.readouterr().out
    eeprom = tmp_path / "e.bin"
    assert main(["tare", "--port", f"{url}&eeprom={eeprom}", "--samples", "20", "--save"]) == 0
    out = capsys.readouterr().out
    assert "tare over 20 samples: Fx" in out and "configuration saved to EEPROM" in out
    with Device(f"{url}&eeprom={eeprom}") as dev:
        assert dev.info().status & P.Status.TARE_ACTIVE
    assert main(["stream", "--port", url, "--duration", "0.3", "--rate", "500",
                 "--interval", "0.05"]) == 0
    captured = capsys.readouterr()
    lines = captured.out.strip().splitlines()
    assert len(lines) >= 3 and all(line.startswith("t ") and line.endswith(" ok") for line in lines)
    assert "0 lost in 0 gaps" in captured.err


@pytest.mark.parametrize("argv, message", [
    (["log", "--port", "delta6sim://", "-o", "x.csv", "--duration", "-1"],
     "--duration must be positive"),
    (["tare", "--port", "delta6sim://", "--samples", "0"], "--samples must be at least 1"),
    (["tare", "--port", "delta6sim://", "--samples", "x"], "--samples takes a whole number"),
    (["stream", "--port", "delta6sim://", "--rate", "70000"], "--rate must be at most 65535"),
])
def test_bad_arguments_exit_2(capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and message in capsys.readouterr().err


def test_a_port_that_is_not_there(capsys):
    assert main(["info", "--port", "/dev/delta6-nothing-here"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("delta6 info: error: cannot open /dev/delta6-nothing-here") and \
        err.count("\n") == 1
    assert main(["info", "--port", "delta6sim://?bogus=1"]) == 2
    assert "unknown option 'bogus'" in capsys.readouterr().err


def test_a_device_restart_ends_the_log_with_what_came_before(tmp_path, capsys, monkeypatch):
    """After a reboot the device's clock starts again; the log keeps the samples before it."""
    original = Device.read_block
    calls = {"n": 0}

    def rebooting(self, *a, **kw):
        block = original(self, *a, **kw)
        calls["n"] += 1
        if calls["n"] == 3:                     # pretend the clock went back mid-block
            block.t[len(block) // 2:] -= 10.0
        return block

    monkeypatch.setattr(Device, "read_block", rebooting)
    out = tmp_path / "reboot.csv"
    assert main(["log", "--port", "delta6sim://", "-o", str(out), "--rate", "500",
                 "--duration", "5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "the device restarted during the log (its clock went back)" in err
    log = read_log(out, require_complete_rows=False)
    assert err.endswith(f"keeps the {len(log)} samples received before") and len(log) > 0


def test_decode_stops_at_a_device_restart(tmp_path, capsys):
    first, _ = capture_from_sim(0.2, raw=False)
    second, _ = capture_from_sim(0.1, raw=False)             # a fresh boot: clock from 0
    cap_file = tmp_path / "reboot.bin"
    cap_file.write_bytes(first + second)
    out = tmp_path / "r.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "the device restarted at frame" in err and "the 51 samples after it" in err
    assert "101 samples, 0 missing in 0 gaps" in err
    log = read_log(out, require_complete_rows=False)
    assert len(log) == 101 and log.t[-1] == 0.2
