"""INFO records with a valid CRC whose fields a Delta6 never sends: names that are not printable
ASCII, joint limits, cutoffs, tool frames and overload limits out of range. They are refused
in one line (``info_problem``), and a log header stays one printable line whatever it is given.
"""
from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.cli import main
from delta6.link import protocol as P
from delta6.link.infocheck import info_problem
from delta6.link.logfile import open_log_writer, read_log

from support.streams import an_info

NAME_OFFSETS = {"design_name": 12, "calibration_name": 132, "model_name": 162}


def _info_with_name(key: str, name: bytes) -> bytes:
    """The frame of a valid INFO whose name field ``key`` holds ``name`` (NUL-padded)."""
    payload = bytearray(P.unframe(P.encode_info(an_info())[:-1]))
    at = NAME_OFFSETS[key]
    payload[at:at + 24] = name[:23].ljust(24, b"\x00")
    return P.frame(bytes(payload))


def _sent(info: P.Info) -> P.Info:
    """``info`` through the wire: its floats become the float32s a device sends."""
    return P.parse_payload(P.unframe(P.encode_info(info)[:-1]))


def test_the_sent_name_is_the_parsed_name():
    frame = _info_with_name("model_name", b"abc")
    assert P.parse_payload(P.unframe(frame[:-1])).model_name == "abc"


@settings(max_examples=150, deadline=None)
@given(key=st.sampled_from(sorted(NAME_OFFSETS)),
       name=st.binary(min_size=1, max_size=23).filter(lambda b: b"\x00" not in b))
def test_a_name_is_accepted_exactly_when_it_is_printable_ascii(key, name):
    info = P.parse_payload(P.unframe(_info_with_name(key, name)[:-1]))
    printable = all(0x20 <= b < 0x7F for b in name)
    problem = info_problem(info)
    assert (problem is None) == printable, (name, problem)
    if problem is not None:
        assert problem.isascii() and problem.isprintable() and "not printable ASCII" in problem


@pytest.mark.parametrize("changes, words", [
    ({"joint_limit_rad": -1.0}, "joint limit"),
    ({"joint_limit_rad": 0.0}, "joint limit"),
    ({"joint_limit_rad": 1000.0}, "joint limit"),
    # (pi/2 itself arrives as float32(pi/2), as a design's 1.57079632 does: not told apart)
    ({"joint_limit_rad": float(np.nextafter(np.float32(math.pi / 2), np.float32(2)))},
     "joint limit"),
    ({"filter_hz": math.nan}, "cutoff"),
    ({"filter_hz": -1.0}, "cutoff"),
    ({"filter_hz": 0.45 * 350 + 1}, "cutoff"),
    ({"tool_translation": (math.nan, 0.0, 0.0)}, "tool frame"),
    ({"tool_translation": (0.0, 0.0, -1.5)}, "tool frame"),
    ({"tool_rpy": (0.0, 7.0, 0.0)}, "tool frame"),
    ({"tool_rpy": (0.0, 0.0, math.inf)}, "tool frame"),
    ({"limits": (40000, 0, 0, 0, 0, 0)}, "overload limit"),
])
def test_out_of_range_fields_are_refused(changes, words):
    assert words in info_problem(_sent(an_info(**changes)))


@pytest.mark.parametrize("changes", [
    {"joint_limit_rad": 0.01}, {"joint_limit_rad": 1.5}, {"filter_hz": 0.45 * 350},
    {"tool_translation": (1.0, -1.0, 1.0)}, {"tool_rpy": (2 * math.pi, -2 * math.pi, 0.0)},
    {"limits": (32767, 0, 1, 0, 0, 0)},
])
def test_the_bounds_themselves_are_accepted(changes):
    assert info_problem(_sent(an_info(**changes))) is None


@given(st.floats(0.01, math.pi / 2, exclude_max=True))
def test_every_joint_limit_a_design_accepts_is_accepted_from_the_wire(limit):
    """Design validation takes [0.01, pi/2) in float64; the device sends float32, which
    rounds 1.57079632 up to 1.5707963705 (above pi/2): it was refused."""
    assert info_problem(_sent(an_info(joint_limit_rad=limit))) is None


@pytest.mark.parametrize("name", [b"\xe9t\xe9", b"x\ny", b"\xff\xfe", b"a\x1b[2Jb"])
def test_decode_refuses_a_capture_whose_info_has_such_a_name(tmp_path, name):
    capture = tmp_path / "c.bin"
    capture.write_bytes(P.encode_event(P.EventCode.BOOT, 0) + _info_with_name("design_name", name)
                        + b"".join(P.encode_wrench(i, 1000 + 4000 * i, 0, (i,) * 6)
                                   for i in range(10)))
    for output in ("c.csv", "c.mcap"):
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            status = main(["decode", str(capture), "-o", str(tmp_path / output)])
        assert status == 2 and err.getvalue().count("\n") == 1, err.getvalue()
        assert "not printable ASCII" in err.getvalue()
        assert list(tmp_path.glob(output + "*")) == []


@settings(max_examples=60, deadline=None)
@given(value=st.text(max_size=30))
@pytest.mark.parametrize("suffix", [".csv", ".mcap"])
def test_any_header_value_is_written_as_one_line_and_read_back(tmp_path_factory, suffix, value):
    """What slips past the checks (a name in a header) is escaped, never a crash mid-log."""
    path = tmp_path_factory.mktemp("h") / ("log" + suffix)
    with open_log_writer(path, {"design": value, "source": "test"}) as log:
        log.write(0.0, [0.0] * 6, [0.0] * 6)
    meta = read_log(path).meta
    assert meta["source"] == "test"
    written = meta["design"]
    assert written.isascii() and written.isprintable()
    # (a CSV reader strips what a spreadsheet pads a header line with: spaces, commas)
    if value.isascii() and value.isprintable() and value == value.strip(" ,"):
        assert written == value
