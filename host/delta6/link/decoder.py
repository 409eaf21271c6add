"""Incremental stream decoder: feed received bytes, get records; every loss is counted.

Frames end at 0x00 (COBS), so after any damage the decoder resynchronises at the next 0x00.
A damaged frame often ends with an intact record (garbage or a lost delimiter in front of it
merges the two): the decoder then checks the tail of the damaged frame for a complete record
of each known length and keeps it, so every intact record after the damage is delivered. A
record is only ever yielded with a valid CRC and the length its type requires.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

from delta6.link import cobs
from delta6.link.protocol import (
    ENCODED_LENGTHS,
    ENCODED_SIZES,
    MAX_RECORD_SIZE,
    ProtocolError,
    checked_payload,
    parse_payload,
    unframe,
)

#: Frames longer than this are discarded without decoding (largest record + slack).
MAX_FRAME = MAX_RECORD_SIZE + 64
_TAIL_LENGTHS = sorted(set().union(*ENCODED_LENGTHS.values()))


@dataclass
class DecoderStats:
    """What the decoder saw. ``resyncs`` counts damaged stretches (each rejected frame)."""

    bytes_received: int = 0
    frames: int = 0              # delimited frames seen (empty ones not counted)
    records: int = 0             # records delivered
    crc_errors: int = 0          # valid COBS, wrong CRC
    cobs_errors: int = 0         # not valid COBS
    length_errors: int = 0       # valid CRC, too short for its type
    unknown_types: int = 0       # valid CRC, a type this version does not know
    oversize: int = 0            # longer than any record
    resyncs: int = 0             # rejected frames: the decoder skipped to the next 0x00
    bytes_discarded: int = 0     # bytes of rejected frames not recovered as a record
    recovered: int = 0           # intact records found at the end of a damaged frame
    startup_bytes: int = 0       # a partial frame before the first delimiter

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def errors(self) -> int:
        return self.crc_errors + self.cobs_errors + self.length_errors + self.oversize


def decode_frame(encoded: bytes, stats: DecoderStats, first: bool = False):
    """One delimited frame (without the 0x00) to a record, or None; updates ``stats``.

    ``first`` marks the bytes before the first delimiter of a stream: they may be the end of a
    frame sent before we listened, so failing them is not counted as an error."""
    if not encoded:
        return None
    stats.frames += 1
    decoded = cobs.decode(encoded) if len(encoded) <= MAX_FRAME else None
    payload = None if decoded is None else checked_payload(decoded)
    if payload is not None:
        try:
            record = parse_payload(payload)
        except ProtocolError:
            if payload[0] in _KNOWN_TYPES:
                stats.length_errors += 1
            else:
                stats.unknown_types += 1
            stats.bytes_discarded += len(encoded)
            stats.resyncs += 1
            return None
        stats.records += 1
        return record
    record, used = _recover_tail(encoded)
    if first:
        stats.frames -= 1
        stats.startup_bytes += len(encoded) - used
    else:
        if len(encoded) > MAX_FRAME:
            stats.oversize += 1
        elif decoded is None:
            stats.cobs_errors += 1
        else:
            stats.crc_errors += 1
        stats.resyncs += 1
        stats.bytes_discarded += len(encoded) - used
    if record is not None:
        stats.recovered += 1
        stats.records += 1
    return record


_KNOWN_TYPES = frozenset(int(t) for t in ENCODED_SIZES)


def _recover_tail(encoded: bytes):
    """A complete record at the end of a damaged frame: (record, its length) or (None, 0)."""
    for length in _TAIL_LENGTHS:
        if length >= len(encoded):
            break
        payload = unframe(encoded[-length:])
        if payload is None or length not in ENCODED_LENGTHS.get(payload[0], ()):
            continue
        return parse_payload(payload), length
    return None, 0


class StreamDecoder:
    """Feed bytes in any chunking; :meth:`feed` returns the records completed by them."""

    def __init__(self):
        self.stats = DecoderStats()
        self._partial = b""
        self._synced = False

    def feed(self, data: bytes) -> list:
        self.stats.bytes_received += len(data)
        if b"\x00" not in data:
            self._partial += data
            if len(self._partial) > MAX_FRAME:     # bound memory on a stream without 0x00
                self._drop_partial()
            return []
        chunks = (self._partial + data).split(b"\x00")
        self._partial = chunks.pop()
        out = []
        for chunk in chunks:
            record = decode_frame(chunk, self.stats, first=not self._synced)
            self._synced = True
            if record is not None:
                out.append(record)
        return out

    def _drop_partial(self) -> None:
        # Keep the last MAX_FRAME bytes: a frame ending later can still be recovered.
        excess = len(self._partial) - MAX_FRAME
        self._partial = self._partial[excess:]
        if self._synced:
            self.stats.bytes_discarded += excess
        else:
            self.stats.startup_bytes += excess

    @property
    def pending_bytes(self) -> int:
        """Bytes of an unfinished frame held back."""
        return len(self._partial)


class SequenceTracker:
    """Unwraps 16-bit sequence numbers and 32-bit device times; counts gaps.

    A gap is a jump of more than one in the sequence; ``lost`` sums the missing records. The
    sequence counts every data record the device produced, sent or not, so a gap means a
    record was lost on the device (transmit queue full), on the link, or in the decoder."""

    def __init__(self):
        self.reset()
        self.gaps = 0
        self.lost = 0
        self.duplicates = 0

    def reset(self) -> None:
        """Forget the history (the device rebooted: its counters restart)."""
        self._seq = None
        self._time = None

    def update(self, seq16: int, time32: int) -> tuple[int, int] | None:
        """(unwrapped seq, unwrapped time in us), or None for a repeated record."""
        if self._seq is None:
            self._seq, self._time = seq16, time32
            return self._seq, self._time
        step = (seq16 - self._seq) & 0xFFFF
        if step == 0:
            self.duplicates += 1
            return None
        if step > 1:
            self.gaps += 1
            self.lost += step - 1
        self._seq += step
        self._time += (time32 - self._time) & 0xFFFFFFFF
        return self._seq, self._time
