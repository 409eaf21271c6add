"""delta6 log against a device that does not answer STOP: one STOP attempt, every queued
record still written, and the summary says the stream may not have stopped."""
from __future__ import annotations

import threading
import time

import pytest

from delta6.cli import main
from delta6.commands import log
from delta6.link import protocol as P
from delta6.link.logfile import read_log

from support.scripted import Scripted


@pytest.mark.parametrize("interrupted", [False, True])
def test_an_unanswered_stop_is_sent_once_and_said(tmp_path, monkeypatch, capsys, interrupted):
    """``interrupted``: a second Ctrl-C lands while the host waits for STOP's answer; it ends
    the wait, not the drain (the records queued were in the capture, not in the log)."""
    halt = threading.Event()
    sent = []

    def records():
        while not halt.wait(0.004):
            i = len(sent)
            sent.append(i)
            device.loop_write(P.encode_wrench(i, 1000 + 4000 * i, 0, (0,) * 6))

    def answer(device, command, request_id):
        if command == P.Command.STOP:
            if interrupted:
                halt.set()
                time.sleep(0.2)              # every record sent is queued by now
                raise KeyboardInterrupt
            return b""                        # a device that no longer hears the host
        if command == P.Command.START:
            threading.Thread(target=records, daemon=True).start()
        return device.normal(command, request_id)

    device = Scripted(answer)
    monkeypatch.setattr(log, "open_device", lambda args, **kw: device.open(handshake=True))
    out = tmp_path / "unstopped.csv"
    try:
        assert main(["log", "--port", "scripted", "-o", str(out), "--duration", "0.3"]) == 0
    finally:
        halt.set()
    assert device.sent.count(P.Command.STOP) == (1 if interrupted else 3)  # one attempt
    last = capsys.readouterr().err.strip().splitlines()[-1]
    why = ("the wait for STOP's answer was cut short" if interrupted
           else "STOP was not acknowledged")
    assert f"; {why}: the device may still be streaming" in last
    if interrupted:
        assert last.endswith("(stopped by SIGINT)")
        assert len(read_log(out, require_complete_rows=False)) == len(sent)
