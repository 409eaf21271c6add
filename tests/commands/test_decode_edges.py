"""`delta6 decode` on captures a real device never sends but a file can hold: every answer is
a log its own reader accepts (status 0) or one line (status 2), never a traceback."""
from __future__ import annotations

import contextlib
import io

import pytest

from delta6.cli import main
from delta6.link import protocol as P
from delta6.link.logfile import read_log

from support.streams import an_info


def decode(tmp_path, frames: bytes, *options: str) -> tuple[int, str]:
    capture = tmp_path / "c.bin"
    capture.write_bytes(P.encode_event(P.EventCode.BOOT, 0) + P.encode_info(an_info()) + frames)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main(["decode", str(capture), "--force", *options])
    assert "Traceback" not in err.getvalue()
    return status, err.getvalue()


@pytest.mark.parametrize("times, sessions", [([1000, 5000, 5000, 9000, 13000], 2),
                                             ([1000, 1000, 1000], 3)])
def test_a_clock_that_stands_still_splits_the_capture_into_readable_sessions(
        tmp_path, times, sessions):
    frames = b"".join(P.encode_wrench(i, t, 0, (i,) * 6) for i, t in enumerate(times))
    for session in range(1, sessions + 1):
        out = tmp_path / f"s{session}.csv"
        status, err = decode(tmp_path, frames, "-o", str(out), "--session", str(session))
        if session > 1:     # the INFO belongs to the first session: the others have no scale
            assert status == 2 and err.count("\n") == 1 and "no device-info" in err, err
            continue
        assert status == 0, err
        assert f"holds {sessions} device sessions" in err
        log = read_log(out, require_complete_rows=False)   # wrench-only: no angles
        assert len(log.t) >= 1
