"""The device subcommands end to end against the simulated device, and ``delta6 decode``."""
from __future__ import annotations

import json

import numpy as np
import pytest

from delta6.cli import COMMAND_MODULES, main
from delta6.core.model import wrench as model_wrench
from delta6.link import protocol as P
from delta6.link.crc import crc16
from delta6.link.device import Device
from delta6.link.logfile import read_log
from delta6.sim.simdevice import SimulatedDevice

from support.streams import make_frames


def capture_from_sim(seconds=0.5, raw=True, **kwargs) -> tuple[bytes, SimulatedDevice]:
    # Room for the boot records (250 bytes with INFO) and the first data record at once: the
    # stream starts at the device's first sample, before the boot records drained.
    kwargs.setdefault("tx_capacity", 512)
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
    assert "1 missing in 1 gaps, 0 flagged, 1 damaged frames" in err
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
    assert log.status[0] == P.Status.CONFIG_DEFAULTS | P.Status.STREAM_CHANGED    # after START
    assert (log.status[1:] == P.Status.CONFIG_DEFAULTS).all()


def test_decode_says_when_the_capture_ends_inside_a_frame(tmp_path, capsys):
    data, _ = capture_from_sim()
    cut = data.rindex(b"\x00", 0, len(data) - 1) + 11     # ten bytes into the last frame
    cap_file = tmp_path / "cut.bin"
    cap_file.write_bytes(data[:cut])
    assert main(["decode", str(cap_file), "-o", str(tmp_path / "cut.csv")]) == 0
    assert "ends 10 bytes into an unfinished frame" in capsys.readouterr().err
    cap_file.write_bytes(data)
    assert main(["decode", str(cap_file), "-o", str(tmp_path / "whole.csv")]) == 0
    assert "unfinished frame" not in capsys.readouterr().err


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
    assert "(stopped by SIGINT)" in capsys.readouterr().err
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


def test_info_says_why_the_configuration_fell_back_to_defaults(capsys, tmp_path):
    eeprom = tmp_path / "e.bin"
    url = f"delta6sim://?eeprom={eeprom}"
    assert main(["info", "--port", url]) == 0                 # never saved: erased
    assert "no valid configuration (EEPROM erased or never saved)" in capsys.readouterr().out
    with Device(url) as dev:
        dev.save_config()
    assert main(["info", "--port", url]) == 0
    assert "no valid configuration" not in capsys.readouterr().out
    blob = bytearray(eeprom.read_bytes())
    blob[P.CONFIG_LAYOUT.offsets["rate_hz"]] ^= 1               # a flipped bit: the CRC fails
    eeprom.write_bytes(bytes(blob))
    assert main(["info", "--port", url, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["config_problem"], out["config_problem_text"]) == (P.ConfigProblem.BAD_CRC,
                                                                  "CRC mismatch")
    assert out["status"] & P.Status.CONFIG_DEFAULTS


def test_info_says_when_the_saved_rate_was_lowered(capsys, tmp_path):
    eeprom = tmp_path / "e.bin"
    url = f"delta6sim://?eeprom={eeprom}"
    with Device(url) as dev:
        dev.save_config()
        highest = dev.info().max_rate_hz
    blob = P.CONFIG_LAYOUT.unpack(eeprom.read_bytes()[:P.CONFIG_BLOB_SIZE])
    blob["rate_hz"] = highest + 1                  # as a faster firmware image saved it
    body = P.CONFIG_LAYOUT.pack(**blob)
    eeprom.write_bytes(body + crc16(body).to_bytes(2, "big"))
    assert main(["info", "--port", url]) == 0
    out = capsys.readouterr().out
    assert f"rate {highest} Hz" in out and "no valid configuration" not in out
    assert "note: the EEPROM configuration was saved at a rate above" in out


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
    # An EEPROM image the simulated device could never save: refused when the port opens.
    assert main(["tare", "--port", "delta6sim://?eeprom=/nonexistent/dir/e.bin", "--save"]) == 2
    err = capsys.readouterr().err
    assert "the folder of eeprom=/nonexistent/dir/e.bin does not exist" in err
    assert err.count("\n") == 1


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


def test_decode_splits_a_capture_at_a_device_restart(tmp_path, capsys):
    first, _ = capture_from_sim(0.2, raw=False)
    second, _ = capture_from_sim(0.1, raw=False)             # a fresh boot: clock from 0
    cap_file = tmp_path / "reboot.bin"
    cap_file.write_bytes(first + second)
    out = tmp_path / "r.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "101 samples, 0 missing in 0 gaps" in err
    assert "the capture holds 2 device sessions (the device restarted; 1: 101 samples, " \
           "2: 51 samples): this log has session 1" in err
    log = read_log(out, require_complete_rows=False)
    assert len(log) == 101 and log.t[-1] == 0.2 and log.meta["session"] == "1 of 2"
    assert main(["decode", str(cap_file), "-o", str(tmp_path / "r2.csv"), "--session", "2"]) == 0
    assert "51 samples, 0 missing in 0 gaps" in capsys.readouterr().err
    second_log = read_log(tmp_path / "r2.csv", require_complete_rows=False)
    assert second_log.t[0] == 0.0 and second_log.seq[0] == 0 and len(second_log) == 51
    assert main(["decode", str(cap_file), "-o", str(tmp_path / "r3.csv"), "--session", "3"]) == 2
    assert "--session 3, but the capture holds 2 sessions" in capsys.readouterr().err


def without_boot_events(stream: bytes) -> bytes:
    """The stream minus its BOOT events (what a capture opened after the boot holds)."""
    frames = [f + b"\x00" for f in stream.split(b"\x00")[:-1]]
    boot = P.encode_event(P.EventCode.BOOT, 0)
    return b"".join(f for f in frames if f != boot)


def test_joined_captures_are_two_sessions_even_without_a_boot_event(tmp_path, capsys):
    """A capture appended to an older one of another boot: the counters run backwards, which
    must not be read as a 71-minute clock wrap with 65,000 records missing."""
    first, _ = capture_from_sim(0.3, raw=False)
    second, _ = capture_from_sim(0.1, raw=False)
    cap_file = tmp_path / "joined.bin"
    cap_file.write_bytes(first + without_boot_events(second))
    out = tmp_path / "j.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "151 samples, 0 missing in 0 gaps" in err
    assert "2 device sessions (the device restarted, 1 of them found by counters that began " \
           "again; 1: 151 samples, 2: 51 samples)" in err
    log = read_log(out, require_complete_rows=False)
    assert len(log) == 151 and log.t[-1] == 0.3 and np.all(np.diff(log.seq) == 1)


def one_line_error(capsys, command: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"delta6 {command}: error: "), err
    return err.strip()


def test_output_paths_are_checked_before_anything_runs(tmp_path, capsys):
    folder = tmp_path / "out"
    folder.mkdir()
    capture = tmp_path / "c.bin"
    capture.write_bytes(capture_from_sim(0.1)[0])
    cases = [
        (["log", "--port", "delta6sim://", "-o", f"{folder}/", "--duration", "0.2"], "log",
         "is a folder; give a file name"),
        (["log", "--port", "delta6sim://", "-o", str(tmp_path / "no" / "x.csv")], "log",
         "the folder"),
        (["decode", str(capture), "-o", f"{folder}/"], "decode", "is a folder; give a file name"),
        (["decode", str(capture), "-o", str(folder)], "decode", "is a folder; give a file name"),
    ]
    for argv, command, words in cases:
        assert main(argv) == 2
        assert words in one_line_error(capsys, command)
    # Nothing was left beside the folder (the log used to stream into "out/.partial").
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.bin", "out"]
    assert list(folder.iterdir()) == []


def test_log_never_replaces_a_file_without_force(tmp_path, capsys):
    out = tmp_path / "run.csv"
    out.write_text("yesterday's run")
    argv = ["log", "--port", "delta6sim://", "-o", str(out), "--duration", "0.2"]
    assert main(argv) == 2
    assert "run.csv exists (not replaced; --force replaces it)" in one_line_error(capsys, "log")
    assert out.read_text() == "yesterday's run"
    out.unlink()
    left = tmp_path / "run.csv.partial"
    left.write_text("what a crash left")
    assert main(argv) == 2
    assert "run.csv.partial exists (an interrupted run left it" in one_line_error(capsys, "log")
    assert main(argv + ["--force"]) == 0
    assert len(read_log(out, require_complete_rows=False)) > 0 and not left.exists()


def test_a_capture_that_exists_is_refused_before_the_port_is_opened(tmp_path, capsys):
    capture = tmp_path / "cap.bin"
    capture.write_bytes(b"first session")
    out = tmp_path / "l.csv"
    argv = ["log", "--port", "delta6sim://", "-o", str(out), "--duration", "0.2",
            "--capture", str(capture)]
    assert main(argv) == 2
    assert "cap.bin exists (not replaced; --force replaces it)" in one_line_error(capsys, "log")
    assert capture.read_bytes() == b"first session" and not out.exists()
    assert main(argv + ["--force"]) == 0
    capsys.readouterr()
    assert main(["decode", str(capture), "-o", str(tmp_path / "d.csv")]) == 0
    assert "device sessions" not in capsys.readouterr().err


def test_summaries_count_flagged_samples(tmp_path, capsys):
    out = tmp_path / "f.csv"
    url = "delta6sim://?encoder_fault=2:0.2&seed=3"
    assert main(["log", "--port", url, "-o", str(out), "--duration", "0.4", "--rate", "500"]) == 0
    err = capsys.readouterr().err
    log = read_log(out, require_complete_rows=False)
    flags = int(np.count_nonzero(log.status & P.Status.ENCODER2))
    assert flags > 10 and f"; {flags} flagged; " in err
    assert main(["stream", "--port", url, "--duration", "0.3", "--rate", "500"]) == 0
    assert " flagged" in capsys.readouterr().err


def test_decode_writes_the_rate_and_counts_unknown_records_apart(tmp_path, capsys):
    data, _ = capture_from_sim(0.3, raw=False)
    newer = P.frame(bytes([0x42]) + bytes(range(1, 20)))       # a newer minor version's
    cap_file = tmp_path / "n.bin"
    cut = data.index(b"\x00", 3000) + 1                          # between two frames
    cap_file.write_bytes(data[:cut] + newer + data[cut:])
    out = tmp_path / "n.csv"
    assert main(["decode", str(cap_file), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "0 damaged frames" in err and "1 records of unknown type ignored" in err
    log = read_log(out, require_complete_rows=False)
    assert log.meta["rate_hz"] == "500" and log.meta["wrench_source"] == "device"


@pytest.mark.parametrize("change, words", [
    (dict(lsb_mantissa=(3, 1, 1, 2, 2, 2)), "axis 1 has a wrench step of 3e-3"),
    (dict(protocol=(2, 0)), "protocol 2.0; this delta6 reads 1.x: update the host"),
])
def test_decode_refuses_an_unusable_info_record(tmp_path, capsys, change, words):
    data, _ = capture_from_sim(0.1, raw=False)
    frames = [f + b"\x00" for f in data.split(b"\x00")[:-1]]
    out_frames = []
    for f in frames:
        payload = P.unframe(f[:-1])
        record = P.parse_payload(payload) if payload else None
        out_frames.append(P.encode_info(record._replace(**change))
                          if isinstance(record, P.Info) else f)
    cap_file = tmp_path / "bad.bin"
    cap_file.write_bytes(b"".join(out_frames))
    assert main(["decode", str(cap_file), "-o", str(tmp_path / "b.csv")]) == 2
    assert words in one_line_error(capsys, "decode")
    assert not (tmp_path / "b.csv").exists() and not (tmp_path / "b.csv.partial").exists()


def test_info_json_has_null_where_a_value_is_unknown(capsys):
    import json
    assert main(["info", "--port", "delta6sim://", "--json"]) == 0
    out = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(c))
    assert out["telemetry"]["temperature_c"] is None
    assert out["telemetry"]["temperature_centi"] is None


def test_top_level_help_describes_the_tool_and_the_exit_statuses(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    out = " ".join(capsys.readouterr().out.split())       # argparse wraps the lines
    assert exc.value.code == 0
    assert "Delta6, a low-cost 6-axis force/torque sensor:" in out
    assert "Exit status: 0 done; 2 bad input" in out and "143 SIGTERM" in out
    assert "Each subcommand lives" not in out


@pytest.mark.parametrize("command", COMMAND_MODULES)
def test_every_command_has_working_help(capsys, command):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("usage: delta6 ")


def test_the_simulated_device_reports_the_firmware_version_of_the_board(root):
    import re
    header = (root / "firmware/lib/delta6_core/src/delta6_version.h").read_text()
    version = tuple(int(v) for v in re.findall(r"kFirmwareVersion\w+ = (\d+);", header))
    with Device("delta6sim://") as dev:
        assert dev.info().firmware == version == (1, 0, 0)
    app = (root / "firmware/src/app.cpp").read_text()
    assert "kFirmwareVersionMajor, delta6::kFirmwareVersionMinor" in app
