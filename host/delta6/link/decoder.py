"""Incremental stream decoder: feed received bytes, get records; every loss is counted.

Frames end at 0x00 (COBS), so after any damage the decoder resynchronises at the next 0x00.
A damaged frame often ends with an intact record (garbage or a lost delimiter in front of it
merges the two): the decoder then checks the tail of the damaged frame for a complete record
of each known length and keeps it, so every intact record after the damage is delivered. A
record is only ever yielded with a valid CRC and the length its type requires.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from delta6.core.design import MAX_RATE_HZ
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
    length_errors: int = 0       # valid CRC, a length no version sends for its type
    unknown_types: int = 0       # valid CRC, a type this version does not know
    oversize: int = 0            # longer than MAX_FRAME: discarded undecoded
    resyncs: int = 0             # rejected frames: the decoder skipped to the next 0x00
    bytes_discarded: int = 0     # bytes of rejected frames not recovered as a record
    recovered: int = 0           # intact records found at the end of a damaged frame
    startup_bytes: int = 0       # a partial frame before the first delimiter (at most
                                 # MAX_FRAME: older bytes are noise, oversize and discarded)

    def as_dict(self) -> dict:
        return asdict(self)

    @property
    def errors(self) -> int:
        return self.crc_errors + self.cobs_errors + self.length_errors + self.oversize


def decode_frame(encoded: bytes, stats: DecoderStats, first: bool = False, dropped: int = 0):
    """One delimited frame (without the 0x00) to a record, or None; updates ``stats``.

    ``first`` marks the bytes before the first delimiter of a stream: their last MAX_FRAME
    may be the end of a frame sent before we listened, so failing them is not counted as an
    error. Bytes before those are no frame's: an oversize error, discarded (a link at the
    wrong baud rate sends no 0x00 for long, and must not look healthy).

    ``dropped`` is how many bytes of this frame came before ``encoded`` and were already
    discarded by the caller, which counted them as the frame's oversize error and resync
    (:class:`StreamDecoder` bounds its memory): the frame is judged at its full length."""
    if not encoded:
        return None
    stats.frames += 1
    total = len(encoded) + dropped
    decoded = cobs.decode(encoded) if total <= MAX_FRAME else None
    payload = None if decoded is None else checked_payload(decoded)
    if payload is not None:
        if payload[0] not in _KNOWN_TYPES:
            # A record of a newer minor version (or a command echoed back): intact, so not
            # damage; ignored and counted (docs/protocol.md, "Versioning").
            stats.unknown_types += 1
            return None
        try:
            record = parse_payload(payload)
        except ProtocolError:
            stats.length_errors += 1
            stats.bytes_discarded += len(encoded)
            stats.resyncs += 1
            return None
        stats.records += 1
        return record
    record, used = _recover_tail(encoded)
    if first:
        stats.frames -= 1
        noise = max(0, total - MAX_FRAME)
        stats.startup_bytes += total - noise - used
        stats.bytes_discarded += noise - dropped
        if noise and not dropped:
            stats.oversize += 1
            stats.resyncs += 1
    else:
        if total > MAX_FRAME:
            if not dropped:
                stats.oversize += 1
                stats.resyncs += 1
        else:
            stats.cobs_errors += decoded is None
            stats.crc_errors += decoded is not None
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
        self._dropped = 0           # bytes of the unfinished frame discarded before _partial
        self._synced = False

    def feed(self, data: bytes) -> list:
        self.stats.bytes_received += len(data)
        if b"\x00" not in data:
            self._partial = self._bounded(self._partial + data)  # memory on a stream without 0x00
            return []
        chunks = (self._partial + data).split(b"\x00")
        out = []
        for chunk in chunks[:-1]:
            record = decode_frame(chunk, self.stats, first=not self._synced, dropped=self._dropped)
            self._synced, self._dropped = True, 0
            if record is not None:
                out.append(record)
        # Bounded only now: the frames above were judged at their full length (the bulk
        # decoder's counts, in any chunking).
        self._partial = self._bounded(chunks[-1])
        return out

    def _bounded(self, partial: bytes) -> bytes:
        """The last MAX_FRAME bytes of an unfinished frame (a frame ending later can still be
        recovered from them); the older ones are discarded, and the frame is counted as
        oversize once, as decode_frame counts it (live: a link without 0x00 shows at once)."""
        excess = len(partial) - MAX_FRAME
        if excess <= 0:
            return partial
        self.stats.bytes_discarded += excess
        if not self._dropped:
            self.stats.oversize += 1
            self.stats.resyncs += 1
        self._dropped += excess
        return partial[excess:]

    @property
    def pending_bytes(self) -> int:
        """Bytes of an unfinished frame held back."""
        return len(self._partial)


#: The highest sample rate a Delta6 can be asked for (the rate is a u16 in START).
MAX_PROTOCOL_RATE_HZ = MAX_RATE_HZ


def continues(seq_step, time_step_us, max_rate_hz: float = MAX_PROTOCOL_RATE_HZ):
    """Whether a data record can follow the previous one of the same device session, from the
    steps (modulo 2^16 and 2^32) between them; works on scalars and numpy arrays.

    Neither counter runs backwards within a session, the clock moves on between two records
    (the next one is latched later: a time that stands still is a restart or a joined
    capture, never a sample rate), and the records missing in a gap must
    have fitted into the time it spans at the board's highest rate. A step that breaks any
    rule is a new session (the device restarted, or two captures were joined): unwrapping
    across it would make up a jump of up to 71 minutes and thousands of "missing" records."""
    if isinstance(seq_step, int) and isinstance(time_step_us, int):    # the live path: fast
        return (0 < seq_step < 1 << 15 and 0 < time_step_us < 1 << 31
                and seq_step - 1 <= time_step_us * max_rate_hz * 1.01e-6 + 1)
    seq_step = np.asarray(seq_step, dtype=np.int64)
    time_step_us = np.asarray(time_step_us, dtype=np.int64)
    forward = (seq_step > 0) & (seq_step < 1 << 15) & (time_step_us > 0) & (time_step_us < 1 << 31)
    # seq_step - 1 records fell between the two, each at least one period apart.
    return forward & (seq_step - 1 <= time_step_us * max_rate_hz * 1.01e-6 + 1)


class SequenceTracker:
    """Unwraps 16-bit sequence numbers and 32-bit device times; counts gaps and sessions.

    A gap is a jump of more than one in the sequence; ``lost`` sums the missing records. The
    sequence counts every data record the device produced, sent or not, so a gap means a
    record was lost on the device (transmit queue full), on the link, or in the decoder.
    A record that cannot follow the previous one (:func:`continues`) starts a new session:
    ``session`` counts up, ``restarts`` counts those found that way, and unwrapping starts
    again from that record (a lost BOOT event must not turn a restart into a clock wrap)."""

    def __init__(self, max_rate_hz: float = MAX_PROTOCOL_RATE_HZ):
        self.max_rate_hz = max_rate_hz
        self._seq = None
        self._time = None
        self.session = 0
        self.gaps = 0
        self.lost = 0
        self.duplicates = 0
        self.restarts = 0

    @property
    def in_session(self) -> bool:
        """Whether a record of the current session was seen (False right after a reset)."""
        return self._seq is not None

    def reset(self) -> None:
        """Start a new session (the device announced a reboot: its counters restart)."""
        if self._seq is not None:
            self.session += 1
        self._seq = None
        self._time = None

    def update(self, seq16: int, time32: int) -> tuple[int, int] | None:
        """(unwrapped seq, unwrapped time in us), or None for a repeated record."""
        if self._seq is None:
            self._seq, self._time = seq16, time32
            return self._seq, self._time
        step = (seq16 - self._seq) & 0xFFFF
        time_step = (time32 - self._time) & 0xFFFFFFFF
        if step == 0 and time_step == 0:
            self.duplicates += 1
            return None
        if not continues(step, time_step, self.max_rate_hz):
            self.restarts += 1
            self.reset()
            return self.update(seq16, time32)
        if step > 1:
            self.gaps += 1
            self.lost += step - 1
        self._seq += step
        self._time += time_step
        return self._seq, self._time
