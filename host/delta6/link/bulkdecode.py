"""Vectorised decoding of a captured byte stream (numpy): millions of records per second.

The capture is split at every 0x00; frames with the encoded length of a data record are
COBS-decoded, CRC-checked and parsed all at once per length (a fixed record layout is a numpy
structured dtype). Everything else (info, answers, telemetry, damaged frames) goes through the
incremental decoder's per-frame path, including its recovery of intact records at the end of
damaged frames, so both decoders deliver the same records and count the same damage.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from delta6.link.crc import crc16_rows
from delta6.link.decoder import MAX_PROTOCOL_RATE_HZ, DecoderStats, continues, decode_frame
from delta6.link.protocol import (
    DATA_FRAME_DTYPES,
    ENCODED_SIZES,
    NO_COUNTS,
    Event,
    EventCode,
    Info,
    WrenchRecord,
    raw_counts,
    theta_values,
    wrench_values,
)


@dataclass
class Capture:
    """The data records of a capture in stream order, plus everything else it held."""

    seq: np.ndarray          # unwrapped sequence numbers (int64)
    time_us: np.ndarray      # unwrapped device time (int64)
    status: np.ndarray       # uint16
    wrench_counts: np.ndarray  # (N, 6) int16, INVALID_VALUE where the sample had no wrench
    counts: np.ndarray       # (N, 6) int32 raw encoder counts, NO_COUNTS where not sent
    frame_index: np.ndarray  # position of each record among the capture's frames
    other: list = field(default_factory=list)   # (frame index, record) of non-data records
    stats: DecoderStats = field(default_factory=DecoderStats)
    gaps: int = 0            # jumps in the sequence
    lost: int = 0            # records missing from the sequence
    duplicates: int = 0      # repeated records (dropped)
    trailing_bytes: int = 0  # an unfinished frame at the end of the capture
    session: np.ndarray | None = None   # device session of each record: 0, 1, ...
    unannounced_restarts: int = 0       # sessions that began without a BOOT event seen

    def __len__(self) -> int:
        return len(self.seq)

    @property
    def infos(self) -> list[Info]:
        return [r for _, r in self.other if isinstance(r, Info)]

    @property
    def sessions(self) -> list[slice]:
        """The rows of each device session, in order (a restart or a joined capture starts
        a new one; docs/protocol.md, "Sequence numbers and time")."""
        if not len(self.seq):
            return []
        starts = np.flatnonzero(np.diff(self.session)) + 1
        edges = [0, *starts.tolist(), len(self.seq)]
        return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]

    @property
    def has_counts(self) -> np.ndarray:
        return self.counts[:, 0] >= 0

    def wrench(self, lsb) -> np.ndarray:
        """Wrench in N and N*m: counts x LSB per axis; NaN where the sample had none."""
        return wrench_values(self.wrench_counts, self.status, lsb)

    def theta(self, zero_counts) -> np.ndarray:
        """Encoder angles (rad); NaN where no counts were sent or the encoder failed."""
        return theta_values(self.counts, self.status, zero_counts)


def decode_capture(data: bytes | np.ndarray, max_rate_hz: float | None = None) -> Capture:
    """The records of a capture. ``max_rate_hz`` bounds how many records a gap can hide
    (default: the board's highest rate from the capture's INFO records, else the protocol's);
    it decides where the counters cannot continue and a new session starts."""
    buf = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data
    stats = DecoderStats(bytes_received=len(buf))
    zeros = np.flatnonzero(buf == 0)
    starts = np.concatenate(([0], zeros[:-1] + 1)) if len(zeros) else np.zeros(0, np.int64)
    lengths = zeros - starts
    trailing = len(buf) - (zeros[-1] + 1 if len(zeros) else 0)

    parts = []        # (frame indices, structured records) per data type
    handled = np.zeros(len(starts), dtype=bool)
    handled[lengths == 0] = True
    for kind, dtype in DATA_FRAME_DTYPES.items():
        length = ENCODED_SIZES[kind]
        index = np.flatnonzero(lengths == length)
        if index.size == 0:
            continue
        ok, records = _decode_fixed(buf, starts[index], length, int(kind), dtype)
        handled[index[ok]] = True
        parts.append((index[ok], records))

    # Frames the fast path did not take: the per-frame decoder, in stream order.
    other = []
    recovered = []
    fast_records = sum(len(r) for _, r in parts)
    for i in np.flatnonzero(~handled):
        chunk = buf[starts[i]:zeros[i]].tobytes()
        record = decode_frame(chunk, stats, first=(i == 0))
        if isinstance(record, WrenchRecord):
            recovered.append((i, record))
        elif record is not None:
            other.append((int(i), record))
    stats.frames += fast_records
    stats.records += fast_records
    boots = [i for i, r in other if isinstance(r, Event) and r.code == EventCode.BOOT]
    if max_rate_hz is None:
        infos = [r.max_rate_hz for _, r in other if isinstance(r, Info) and r.max_rate_hz]
        max_rate_hz = max(infos) if infos else MAX_PROTOCOL_RATE_HZ
    capture = _assemble(parts, recovered, boots, _boot_id_changes(other), max_rate_hz)
    capture.other, capture.stats, capture.trailing_bytes = other, stats, int(trailing)
    return capture


def _boot_id_changes(other) -> list[tuple[int, int]]:
    """(frame of the last record with the old boot id, frame of the first with the new one)
    for every change of the boot id that INFO and TELEMETRY records carry (protocol 1.1)."""
    changes, last = [], None
    for frame, record in other:
        boot_id = getattr(record, "boot_id", None)
        if boot_id is None:
            continue
        if last is not None and boot_id != last[1]:
            changes.append((last[0], frame))
        last = (frame, boot_id)
    return changes


def _decode_fixed(buf, starts, length, kind, dtype):
    """COBS + CRC + type check for frames of one encoded length; returns (ok mask, records)."""
    windows = np.lib.stride_tricks.sliding_window_view(buf, length)
    enc = windows[starts]                              # (N, length) copy
    n = len(enc)
    flat = enc.reshape(-1)
    is_code = np.zeros(n * length, dtype=bool)
    # Follow each frame's chain of COBS codes; a valid frame's chain ends exactly at its end.
    rows = np.arange(n)
    pos = np.zeros(n, dtype=np.int64)
    end_ok = np.zeros(n, dtype=bool)
    while rows.size:
        at = rows * length + pos
        is_code[at] = True
        pos = pos + flat[at]
        done = pos >= length
        end_ok[rows[done]] = pos[done] == length
        rows, pos = rows[~done], pos[~done]
    decoded = np.where(is_code.reshape(n, length), 0, enc)[:, 1:]
    ok = end_ok & (decoded[:, 0] == kind)
    ok &= crc16_rows(decoded) == 0
    good = np.ascontiguousarray(decoded[ok])
    return ok, good.view(dtype).reshape(-1)


def _assemble(parts, recovered, boots, boot_changes, max_rate_hz) -> Capture:
    index = [p[0] for p in parts]
    seq = [p[1]["seq"] for p in parts]
    time = [p[1]["time_us"] for p in parts]
    status = [p[1]["status"] for p in parts]
    wrench = [p[1]["wrench"] for p in parts]
    counts = [p[1]["counts"].astype(np.int32) if "counts" in p[1].dtype.names
              else np.full((len(p[1]), 6), NO_COUNTS, np.int32) for p in parts]
    if recovered:
        index.append(np.array([i for i, _ in recovered]))
        seq.append(np.array([r.seq for _, r in recovered]))
        time.append(np.array([r.time_us for _, r in recovered]))
        status.append(np.array([r.status for _, r in recovered]))
        wrench.append(np.array([r.wrench for _, r in recovered]))
        counts.append(raw_counts(r.counts for _, r in recovered))
    if sum(len(i) for i in index) == 0:     # nothing decoded (random bytes, say)
        empty = np.zeros(0, np.int64)
        return Capture(empty, empty, np.zeros(0, np.uint16), np.zeros((0, 6), np.int16),
                       np.zeros((0, 6), np.int32), empty, session=empty)
    frame_index = np.concatenate(index).astype(np.int64)
    order = np.argsort(frame_index, kind="stable")
    frame_index = frame_index[order]
    seq16 = np.concatenate(seq).astype(np.int64)[order]
    time32 = np.concatenate(time).astype(np.int64)[order]
    status = np.concatenate(status).astype(np.uint16)[order]
    wrench = np.concatenate(wrench).astype(np.int16)[order]
    counts = np.concatenate(counts).astype(np.int32)[order]

    # A record equal in sequence and time to the one before is the same record again.
    repeated = (np.diff(seq16) == 0) & (np.diff(time32) == 0)
    keep = np.concatenate(([True], ~repeated))
    duplicates = int((~keep).sum())
    seq16, time32, status, wrench, counts, frame_index = (
        a[keep] for a in (seq16, time32, status, wrench, counts, frame_index))

    seq_step = np.diff(seq16) % 65536
    time_step = np.diff(time32) % 2**32
    # A new session where a BOOT event lies between two records, or where the counters
    # cannot continue (decoder.continues): each session is unwrapped on its own.
    booted = np.zeros(len(seq16), dtype=bool)
    if len(boots):
        after = np.searchsorted(frame_index, np.asarray(boots), side="right")
        booted[after[(after > 0) & (after < len(seq16))]] = True
    jumped = np.concatenate(([False], ~continues(seq_step, time_step, max_rate_hz)))
    # Another boot id: the restart lies between the last record with the old id and the first
    # with the new one (which a rebooted device sends before its first data record); where
    # the counters do not show it in that stretch, the new session starts after the new id.
    for old_frame, new_frame in boot_changes:
        first = int(np.searchsorted(frame_index, old_frame, side="right"))
        after = int(np.searchsorted(frame_index, new_frame, side="right"))
        if 0 < after < len(seq16) and not (jumped | booted)[first:after + 1].any():
            jumped[after] = True
    new = booted | jumped
    new[0] = True
    session = np.cumsum(new) - 1
    seq = _unwrap(seq16, seq_step, new, session)
    time_us = _unwrap(time32, time_step, new, session)
    capture = Capture(seq=seq, time_us=time_us, status=status, wrench_counts=wrench,
                      counts=counts, frame_index=frame_index, duplicates=duplicates,
                      session=session)
    capture.gaps, capture.lost = sequence_counts(seq, session)
    capture.unannounced_restarts = int((jumped & ~booted).sum())
    return capture


def _unwrap(raw, steps, new, session) -> np.ndarray:
    """Raw counter values unwrapped by their steps, starting again at each session start."""
    increments = np.concatenate(([0], steps))
    increments[new] = 0
    total = np.cumsum(increments)
    base = raw[new] - total[new]
    return total + base[session]


def sequence_counts(seq: np.ndarray, session: np.ndarray | None = None) -> tuple[int, int]:
    """(gaps, lost) of unwrapped sequence numbers: jumps of more than one, and the records
    missing in them (as :class:`delta6.link.decoder.SequenceTracker` counts them), within
    each session (the steps between sessions are no gaps)."""
    steps = np.diff(np.asarray(seq, dtype=np.int64))
    if session is not None:
        steps = steps[np.diff(session) == 0]
    return int((steps > 1).sum()), int((steps - 1).clip(0).sum())
