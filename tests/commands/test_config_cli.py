"""The wrench pipeline from the host: Device.set_filter/set_tool/set_limits, ``delta6 config``
and ``delta6 info`` against the simulated device (the firmware core), saved and reloaded."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from delta6.cli import main
from delta6.link import protocol as P
from delta6.link.device import Device, DeviceError, limit_counts


def test_device_methods_round_trip_and_survive_a_power_cycle(tmp_path):
    port = f"delta6sim://?eeprom={tmp_path / 'eeprom.bin'}"
    with Device(port) as dev:
        lsb = dev.info().lsb
        assert dev.set_filter(20) == 20.0
        dev.set_tool((0.0, 0.0, 0.01), (0.0, 0.0, math.pi / 2))
        limits = dev.set_limits([10, None, 20, 0.3, float("nan"), 0])
        assert np.allclose(limits, [10, np.nan, 20, 0.3, np.nan, np.nan], equal_nan=True)
        info = dev.info()
        assert info.limits == tuple(limit_counts([10, None, 20, 0.3, None, 0], lsb))
        assert np.allclose(info.tool_rpy, (0, 0, math.pi / 2))
        dev.save_config()
    with Device(port) as dev:                                  # the board powered up again
        info = dev.info()
        assert info.filter_hz == 20.0 and np.allclose(info.tool_translation, (0, 0, 0.01))
        assert not info.status & P.Status.CONFIG_DEFAULTS
        dev.set_filter(None)
        assert dev.info().filter_hz == 0.0


def test_overload_flags_the_stream_at_the_limits_set():
    """The simulated mechanism moves through most of its joint box: a low Fz limit flags the
    samples over it, exactly those (checked on the values received), and none without limits."""
    with Device("delta6sim://?motion=sine") as dev:
        limit = 2.0
        dev.set_limits([None, None, limit, None, None, None])
        lsb = dev.info().lsb
        dev.start(500)
        time.sleep(1.0)
        block = dev.read_block(timeout=5)
        dev.set_limits([None] * 6)
        dev.flush()
        time.sleep(0.2)
        after = dev.read_block(timeout=5)
    # OVERRANGE: over the limit, or clipped at the wire's range (a value at +-32767 counts
    # may be either: those samples are not judged).
    over = (block.status & P.Status.OVERRANGE) != 0
    fz = block.wrench[:, 2]
    at_range = (np.abs(np.round(block.wrench / lsb)) >= P.MAX_VALUE).any(axis=1)
    assert over.any() and (~over).any()
    assert np.array_equal(over[~at_range], (np.abs(fz) > limit + 1e-9)[~at_range])
    after_at_range = (np.abs(np.round(after.wrench / lsb)) >= P.MAX_VALUE).any(axis=1)
    assert not (after.status[~after_at_range] & P.Status.OVERRANGE).any()


def test_host_refuses_what_it_can_tell_is_wrong_and_a_device_older_than_protocol_1_3():
    with Device("delta6sim://") as dev:
        with pytest.raises(DeviceError, match="within 1 m"):
            dev.set_tool((0, 0, 1.5))
        with pytest.raises(DeviceError, match="beyond the wire's range"):
            dev.set_limits([1000, 0, 0, 0, 0, 0])
        with pytest.raises(DeviceError, match="positive"):
            dev.set_limits([-1, 0, 0, 0, 0, 0])
        for old in ((1, 0), (1, 2)):
            dev._set_info(dev.info()._replace(protocol=old))
            with pytest.raises(DeviceError, match=f"protocol {old[0]}.{old[1]}, the command "
                                                  "needs 1.3: update the firmware"):
                dev.set_filter(10)


def test_an_info_record_of_protocol_1_0_reads_with_the_pipeline_at_its_defaults():
    with Device("delta6sim://") as dev:
        info = dev.info()
    payload = P.unframe(P.encode_info(info)[:-1])
    old = payload[:P.MIN_RECORD_SIZES[P.RecordType.INFO]]
    parsed = P.parse_payload(old)
    assert parsed == info._replace(**P.APPENDED_FIELDS[P.RecordType.INFO])
    # A 1.1 device without the pipeline (INFO up to the boot id) reads with it off.
    boot_id_at = P.RECORD_LAYOUTS[P.RecordType.INFO].offsets["boot_id"]
    pipeline = {k: v for k, v in P.APPENDED_FIELDS[P.RecordType.INFO].items()
                if P.RECORD_LAYOUTS[P.RecordType.INFO].offsets[k] > boot_id_at}
    before = payload[:boot_id_at + 2]
    assert P.parse_payload(before) == info._replace(**pipeline)
    with pytest.raises(P.ProtocolError, match="no version sends that"):
        P.parse_payload(payload[:-3])


def test_config_and_info_commands(tmp_path, capsys):
    port = f"delta6sim://?eeprom={tmp_path / 'eeprom.bin'}"
    assert main(["config", "--port", port, "--filter-hz", "20", "--tool", "0,0,0.05,0,0,90",
                 "--limits", "10,-,20,0.3,0.3,0", "--save"]) == 0
    out = capsys.readouterr().out
    assert "filter: low-pass 20 Hz" in out and "roll, pitch, yaw 0, 0, 90 deg" in out
    assert "Fx 10 N, Fy -, Fz 20 N, Mx 0.3 N*m, My 0.3 N*m, Mz -" in out
    assert "configuration saved" in out
    assert main(["info", "--port", port]) == 0
    out = capsys.readouterr().out
    assert "point 0, 0, 0.05 m" in out and "low-pass 20 Hz" in out
    assert main(["config", "--port", port, "--filter-hz", "off", "--tool", "off",
                 "--limits", "off"]) == 0
    out = capsys.readouterr().out
    assert "filter: off" in out and "tool frame: none" in out and "overload limits: none" in out
    assert main(["config", "--port", port, "--filter-hz", "300"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "0.45 x the sample rate of 200 Hz" in err[0]
    with pytest.raises(SystemExit) as exc:
        main(["config", "--port", port, "--tool", "0,0,1"])
    assert exc.value.code == 2
    assert "--tool takes 6 comma-separated numbers" in capsys.readouterr().err


def test_a_tool_point_with_a_negative_first_coordinate_is_a_value_not_an_option(capsys):
    """argparse reads '-0.02,0,...' after an option as another option (only a single number
    may start with a minus sign); the command line joins it to its option."""
    assert main(["config", "--port", "delta6sim://", "--tool", "-0.02,0,0.05,0,-90,0"]) == 0
    assert "point -0.02, 0, 0.05 m; roll, pitch, yaw 0, -90, 0 deg" in capsys.readouterr().out
    assert main(["config", "--port", "delta6sim://", "--limits", "-,-,20,-,-,-"]) == 0
    assert "Fx -, Fy -, Fz 20 N, Mx -, My -, Mz -" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:                    # still a list of six numbers
        main(["config", "--port", "delta6sim://", "--tool", "-0.02,0"])
    assert exc.value.code == 2
    assert "--tool takes 6 comma-separated numbers" in capsys.readouterr().err


def test_joined_negative_lists_leaves_everything_else_alone():
    from delta6.cli import joined_negative_lists
    argv = ["config", "--port", "x", "--filter-hz", "-1", "--tool=-1,2", "--", "-3,4",
            "--save", "-5,6", "--limits", "-,1,2,3,4,5", "--port", "-x,y", "-,"]
    assert joined_negative_lists(argv) == [
        "config", "--port", "x", "--filter-hz", "-1", "--tool=-1,2", "--", "-3,4",
        "--save=-5,6", "--limits=-,1,2,3,4,5", "--port", "-x,y", "-,"]


@pytest.mark.parametrize("argv, words", [
    (["log", "--port", "delta6sim://", "-o", "{tmp}/z.csv", "--duration", "nan"],
     "--duration takes a finite number"),
    (["stream", "--port", "delta6sim://", "--duration", "nan"], "--duration takes a finite"),
    (["info", "--port", "delta6sim://?rate=-5"], "rate=-5 is outside 1..65535"),
    (["info", "--port", "delta6sim://?speed=nan"], "speed=nan is outside"),
    (["log", "--port", "delta6sim://", "-o", "{tmp}/z.mcap", "--frame-id", ""],
     "--frame-id takes a frame name"),
    (["tare", "--port", "delta6sim://", "--abort", "--save"], "--abort changes nothing"),
])
def test_nan_and_out_of_range_numbers_are_refused_in_one_line(argv, words, tmp_path, capsys):
    """nan passed every range check (a log of one sample with exit 0; NaN in a model card) and
    a negative rate wrapped to 65531 Hz."""
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_config_saves_only_what_the_device_reports_back():
    """A device that ACKs a setting and then reports another (a restart missed, a firmware
    that ignored it) gets nothing saved."""
    from delta6.commands.config import _check_read_back

    from support.streams import an_info

    sent = P.parse_payload(P.unframe(P.encode_info(an_info(
        filter_hz=20.0, tool_translation=(0.01, 0.0, 0.0), tool_rpy=(0.0, 0.0, 0.1),
        limits=(5000, 0, 0, 0, 0, 0)))[:-1]))
    _check_read_back(sent, 20, [0.01, 0, 0, 0, 0, 0.1], [5.0, None, None, None, None, None], "p")
    for cutoff, tool, limits, words in [(15, None, None, "filter of 20 Hz instead of 15"),
                                        (None, [0.0] * 6, None, "tool frame"),
                                        (None, None, [None] * 6, "overload limits")]:
        with pytest.raises(DeviceError, match=words):
            _check_read_back(sent, cutoff, tool, limits, "p")
