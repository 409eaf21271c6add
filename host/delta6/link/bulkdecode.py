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
from delta6.link.decoder import DecoderStats, decode_frame
from delta6.link.protocol import (
    DATA_FRAME_DTYPES,
    ENCODED_SIZES,
    NO_COUNTS,
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

    def __len__(self) -> int:
        return len(self.seq)

    @property
    def infos(self) -> list[Info]:
        return [r for _, r in self.other if isinstance(r, Info)]

    @property
    def has_counts(self) -> np.ndarray:
        return self.counts[:, 0] >= 0

    def wrench(self, lsb) -> np.ndarray:
        """Wrench in N and N*m: counts x LSB per axis; NaN where the sample had none."""
        return wrench_values(self.wrench_counts, self.status, lsb)

    def theta(self, zero_counts) -> np.ndarray:
        """Encoder angles (rad); NaN where no counts were sent or the encoder failed."""
        return theta_values(self.counts, self.status, zero_counts)


def decode_capture(data: bytes | np.ndarray) -> Capture:
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
    capture = _assemble(parts, recovered)
    capture.other, capture.stats, capture.trailing_bytes = other, stats, int(trailing)
    return capture


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


def _assemble(parts, recovered) -> Capture:
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
    if not index:
        empty = np.zeros(0, np.int64)
        return Capture(empty, empty, np.zeros(0, np.uint16), np.zeros((0, 6), np.int16),
                       np.zeros((0, 6), np.int32), empty)
    frame_index = np.concatenate(index).astype(np.int64)
    order = np.argsort(frame_index, kind="stable")
    frame_index = frame_index[order]
    seq16 = np.concatenate(seq).astype(np.int64)[order]
    time32 = np.concatenate(time).astype(np.int64)[order]
    status = np.concatenate(status).astype(np.uint16)[order]
    wrench = np.concatenate(wrench).astype(np.int16)[order]
    counts = np.concatenate(counts).astype(np.int32)[order]

    seq_step = np.diff(seq16) % 65536
    keep = np.concatenate(([True], seq_step != 0))         # a repeated record: drop it
    duplicates = int((~keep).sum())
    seq16, time32, status, wrench, counts, frame_index = (
        a[keep] for a in (seq16, time32, status, wrench, counts, frame_index))
    seq_step = np.diff(seq16) % 65536
    time_step = np.diff(time32) % 2**32
    seq = np.concatenate(([seq16[0]], seq16[0] + np.cumsum(seq_step))) if len(seq16) else seq16
    time_us = (np.concatenate(([time32[0]], time32[0] + np.cumsum(time_step)))
               if len(time32) else time32)
    gaps, lost = sequence_counts(seq)
    return Capture(seq=seq, time_us=time_us, status=status, wrench_counts=wrench, counts=counts,
                   frame_index=frame_index, gaps=gaps, lost=lost, duplicates=duplicates)


def sequence_counts(seq: np.ndarray) -> tuple[int, int]:
    """(gaps, lost) of unwrapped sequence numbers: jumps of more than one, and the records
    missing in them (as :class:`delta6.link.decoder.SequenceTracker` counts them)."""
    steps = np.diff(np.asarray(seq, dtype=np.int64))
    return int((steps > 1).sum()), int((steps - 1).clip(0).sum())
