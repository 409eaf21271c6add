"""Consistent Overhead Byte Stuffing (COBS): frames without 0x00, so 0x00 delimits them.

The encoder matches the firmware's byte for byte (a final block of 254 bytes gets no extra
code byte). :func:`decode` returns None for anything that is not valid COBS.
"""
from __future__ import annotations


def encode(data: bytes) -> bytes:
    out = bytearray()
    start = 0
    n = len(data)
    while True:
        zero = data.find(b"\x00", start, min(n, start + 254))
        if zero < 0:
            end = min(n, start + 254)
            out.append(end - start + 1)
            out += data[start:end]
            if end >= n:
                return bytes(out)
            start = end          # a full 254-byte block: no implicit zero follows
        else:
            out.append(zero - start + 1)
            out += data[start:zero]
            start = zero + 1
            if start == n:       # the data ends with 0x00: one more (empty) block
                out.append(1)
                return bytes(out)


def decode(frame: bytes) -> bytes | None:
    """Decode one frame (without its delimiter); None if it is not valid COBS."""
    if b"\x00" in frame:
        return None
    out = bytearray()
    i = 0
    n = len(frame)
    while i < n:
        code = frame[i]
        j = i + code
        if j > n:
            return None
        out += frame[i + 1:j]
        if code != 0xFF and j < n:
            out.append(0)
        i = j
    return bytes(out)
