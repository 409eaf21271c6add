"""A device that restarts in the middle of what the host is telling it (a brown-out, a
watchdog): the host stops with one line instead of saving the fresh device's defaults or
sending a TARE again to a device that never heard the first one."""
from __future__ import annotations

import pytest

from delta6.link import protocol as P
from delta6.link.device import DeviceRestarted

from support.scripted import Scripted

C = P.Command


SEQUENCE = [C.SET_FILTER, C.SET_LIMITS, C.SAVE_CONFIG]


@pytest.mark.parametrize("announced", [True, False])
@pytest.mark.parametrize("after", SEQUENCE[:-1])
def test_a_restart_between_setting_and_saving_saves_nothing(after, announced):
    def answer(device, command, request_id):
        reply = device.normal(command, request_id)
        return reply + device.reboot(announced) if command == after else reply

    device = Scripted(answer)
    with device.open() as dev:
        with pytest.raises(DeviceRestarted, match="restarted during config"):
            with dev.restart_guard("config"):
                dev.set_filter(20)
                dev.set_limits([5, None, None, None, None, None])
                dev.save_config()
    assert C.SAVE_CONFIG not in device.sent


def test_without_a_restart_the_sequence_runs():
    device = Scripted(Scripted.normal)
    with device.open() as dev:
        with dev.restart_guard("config"):
            dev.set_filter(20)
            dev.save_config()
    assert C.SAVE_CONFIG in device.sent


@pytest.mark.parametrize("announced", [True, False])
def test_a_restart_during_tare_is_reported_and_tare_not_sent_again(announced):
    def answer(device, command, request_id):
        if command == C.TARE:
            return device.reboot(announced)         # the fresh device never answers it
        return device.normal(command, request_id)

    device = Scripted(answer)
    with device.open() as dev:
        dev.info()
        with pytest.raises(DeviceRestarted, match="restarted during tare"):
            dev.tare(10)
    assert device.sent.count(C.TARE) == 1


def test_a_question_is_asked_again_after_a_restart():
    """GET_INFO to a device that restarted meanwhile is harmless: asked again, answered."""
    def answer(device, command, request_id):
        if command == C.GET_INFO and device.sent.count(C.GET_INFO) == 1:
            return device.reboot(True)
        return device.normal(command, request_id)

    device = Scripted(answer)
    with device.open() as dev:
        assert dev.info(refresh=True).boot_id == 2


def test_tare_save_saves_nothing_after_a_restart(monkeypatch, capsys):
    """`delta6 tare --save`: the device restarts after the tare is done and read back (a
    question: no command was under way); SAVE_CONFIG would store the fresh device's defaults,
    so it is not sent, and the command says why in one line."""
    from delta6.cli import main
    from delta6.commands import tare

    def answer(device, command, request_id):
        reply = device.normal(command, request_id)
        if command == C.GET_INFO and C.TARE in device.sent:   # the read-back after the tare
            return reply + device.reboot(True)
        return reply

    device = Scripted(answer)
    monkeypatch.setattr(tare, "open_device", lambda args, **kw: device.open(handshake=True))
    assert main(["tare", "--port", "scripted", "--samples", "5", "--save"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "restarted during tare" in err
    assert C.SAVE_CONFIG not in device.sent


def test_a_restart_seen_just_before_a_command_is_registered_does_not_fail_it():
    """The reader counts a restart between the host reading the restart count and registering
    the command (here: while the request id is drawn): the command goes to the fresh device,
    which answers it; it must succeed (START raised DeviceRestarted, and left the fresh device
    streaming with the host believing it stopped)."""
    device = Scripted(Scripted.normal)
    dev = device.open(handshake=True)
    real = dev._next_request_id

    def restart_meanwhile():
        with dev._cond:
            dev._note_restart()
        return real()

    try:
        dev._next_request_id = restart_meanwhile
        assert dev.start() == 0
        assert dev._started
    finally:
        dev._next_request_id = real
        dev.close()
    assert device.sent.count(P.Command.STOP) == 1        # close() stopped the stream it started
