"""CRC-16/CCITT-FALSE, the checksum of every protocol frame (poly 0x1021, init 0xFFFF).

Frames carry the CRC most significant byte first, so the CRC over a whole decoded frame is 0:
one comparison checks a frame. :func:`crc16_rows` checks many equal-length frames at once.
"""
from __future__ import annotations

import binascii
import functools

import numpy as np

INIT = 0xFFFF


def crc16(data: bytes, crc: int = INIT) -> int:
    return binascii.crc_hqx(data, crc)


@functools.cache
def _tables() -> tuple[np.ndarray, np.ndarray]:
    """The byte table T1 (register after shifting one byte out) and the pair table T2.

    For an MSB-first 16-bit CRC, two input bytes w = b0 << 8 | b1 replace the whole register:
    the CRC after them is T2[crc ^ w], T2 being the register after two zero bytes."""
    one = np.array([binascii.crc_hqx(bytes([b]), 0) for b in range(256)], dtype=np.uint16)
    reg = np.arange(65536, dtype=np.uint32)
    for _ in range(2):
        reg = ((reg << 8) & 0xFFFF) ^ one[reg >> 8]
    return one, reg.astype(np.uint16)


def crc16_rows(rows: np.ndarray, init: int = INIT) -> np.ndarray:
    """CRC of each row of a (N, L) uint8 array, two bytes per table look-up."""
    one, pair = _tables()
    rows = np.asarray(rows, dtype=np.uint8)
    n, length = rows.shape
    crc = np.full(n, init, dtype=np.uint16)
    start = length % 2
    if start:
        crc = ((crc << 8) ^ one[(crc >> 8) ^ rows[:, 0]]).astype(np.uint16)
    for j in range(start, length, 2):
        word = (rows[:, j].astype(np.uint16) << 8) | rows[:, j + 1]
        crc = pair[crc ^ word]
    return crc
