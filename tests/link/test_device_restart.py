"""A device that restarts in the middle of what the host is telling it (a brown-out, a
watchdog): the host stops with one line instead of saving the fresh device's defaults or
sending a TARE again to a device that never heard the first one."""
from __future__ import annotations

import pytest

from delta6.link import protocol as P
from delta6.link.device import Device, DeviceRestarted

from support.streams import an_info

C = P.Command


class Scripted:
    """A device in this process: each command the host writes is answered by ``answer``
    (bytes put on the loop:// port the host reads), and recorded."""

    def __init__(self, answer):
        self.answer = answer
        self.boot_id = 1
        self.sent = []

    def open(self) -> Device:
        dev = Device("loop://", handshake=False, timeout=0.2, retries=2)
        dev.open()
        loop_write = dev._serial.write
        dev._serial.write = lambda data: loop_write(self.reply(data))
        return dev

    def reply(self, data: bytes) -> bytes:
        payload = P.unframe(data[:-1])
        command, request_id = C(payload[0]), payload[1]
        self.sent.append(command)
        return self.answer(self, command, request_id)

    def info(self, request_id: int = 0) -> bytes:
        return P.encode_info(an_info(request_id=request_id, boot_id=self.boot_id))

    def reboot(self, announced: bool) -> bytes:
        self.boot_id += 1
        return (P.encode_event(P.EventCode.BOOT, 0) if announced else b"") + self.info()

    def normal(self, command, request_id) -> bytes:
        if command == C.GET_INFO:
            return self.info(request_id)
        return P.encode_ack(request_id, command, 0)


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
