"""A simulated Delta6 behind a pseudo-terminal, in a process of its own: the device side of the
fault tests. It can be killed like a board can be unplugged, it can garble bytes both ways, and
it keeps a clean copy of every byte the device sent, to check that no logged row is made up,
and of every byte it received, to see when a host's command has arrived.

    python tests/support/ptydevice.py URL [--noise P] [--seed N] [--sent FILE] [--received FILE]

prints the pty's path on stdout, then serves until SIGTERM (or SIGKILL). ``--noise P``: with
probability P per chunk, each direction gets a burst of random bytes or a flipped bit.
"""
from __future__ import annotations

import argparse
import os
import random
import select
import signal
import sys
import tty

import serial

import delta6.link.device  # noqa: F401 - registers the delta6sim:// URL with pyserial


def garble(data: bytes, rnd: random.Random) -> bytes:
    at = rnd.randrange(len(data) + 1)
    if rnd.random() < 0.5 and data:
        flipped = bytearray(data)
        flipped[min(at, len(data) - 1)] ^= 1 << rnd.randrange(8)
        return bytes(flipped)
    burst = bytes(rnd.randrange(256) for _ in range(rnd.randrange(1, 24)))
    return data[:at] + burst + data[at:]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("url")
    parser.add_argument("--noise", type=float, default=0.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sent")
    parser.add_argument("--received")
    args = parser.parse_args()
    rnd = random.Random(args.seed)
    master, slave = os.openpty()      # the slave stays open here: no hang-up between clients
    tty.setraw(slave)
    os.set_blocking(master, False)
    device = serial.serial_for_url(args.url, baudrate=500_000, timeout=0)
    sent = open(args.sent, "wb", buffering=0) if args.sent else None
    received = open(args.received, "wb", buffering=0) if args.received else None
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    print(os.ttyname(slave), flush=True)
    while not stop:
        ready, _, _ = select.select([master], [], [], 0.002)
        if ready:
            try:
                data = os.read(master, 4096)
            except OSError:
                data = b""
            if data:
                if received is not None:
                    received.write(data)
                if args.noise and rnd.random() < args.noise:
                    data = garble(data, rnd)
                device.write(data)
        out = device.read(device.in_waiting)
        if out:
            if sent is not None:
                sent.write(out)
            if args.noise and rnd.random() < args.noise:
                out = garble(out, rnd)
            try:
                os.write(master, out)
            except BlockingIOError:
                pass           # nobody reads the port: the bytes are gone, as on a UART
    device.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
