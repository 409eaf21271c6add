"""A Delta6 scripted in the test's own process: the host's commands, written to a loop://
port, are replaced by the answers a function gives, which the host then reads."""
from __future__ import annotations

from delta6.link import protocol as P
from delta6.link.device import Device

from support.streams import an_info

C = P.Command


class Scripted:
    """A device in this process: each command the host writes is answered by ``answer``
    (bytes put on the loop:// port the host reads), and recorded."""

    def __init__(self, answer):
        self.answer = answer
        self.boot_id = 1
        self.sent = []

    def open(self, handshake: bool = False) -> Device:
        """The host's Device on it; ``handshake``: it has asked for the device info, as a
        Device opened on a real port has."""
        dev = Device("loop://", handshake=False, timeout=0.2, retries=2)
        dev.open()
        self.loop_write = dev._serial.write         # what the device sends unasked
        dev._serial.write = lambda data: self.loop_write(self.reply(data))
        if handshake:
            dev.info(refresh=True)
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
