"""Damaged streams: the decoders never raise, never yield a record with a wrong CRC or length,
yield every intact record after the damage, and count exactly what was injected."""
from __future__ import annotations

import random

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from delta6.link import cobs
from delta6.link import protocol as P
from delta6.link.bulkdecode import decode_capture
from delta6.link.crc import crc16
from delta6.link.decoder import MAX_FRAME, SequenceTracker, StreamDecoder

from support.streams import make_frames

KINDS = ("flip", "drop", "dup", "truncate", "delimiter", "lose_delimiter", "garbage")


def inject(frames: list[bytes], sites: dict[int, str], rnd: random.Random):
    """Damage the frames at ``sites``; returns the stream, the indices of the records that
    must be lost, and the expected resyncs, discarded bytes and recoveries."""
    out, lost = [], set()
    resyncs = discarded = recovered = 0
    for i, frame in enumerate(frames):
        body, kind = bytearray(frame[:-1]), sites.get(i)
        delimiter = b"\x00"
        if kind == "flip":
            at = rnd.randrange(len(body))
            bits = [b for b in range(8) if body[at] != 1 << b]      # never turn it into 0x00
            body[at] ^= 1 << rnd.choice(bits)
            lost.add(i)
            discarded += len(body)
        elif kind == "drop":
            del body[rnd.randrange(len(body))]
            lost.add(i)
            discarded += len(body)
        elif kind == "dup":
            at = rnd.randrange(len(body))
            original = cobs.decode(bytes(body))
            body.insert(at, body[at])
            decoded = cobs.decode(bytes(body))
            if at == 0:          # a repeated first byte leaves the whole frame at the tail
                discarded += 1
                recovered += 1
            elif (decoded is not None and decoded.startswith(original)
                  and not decoded[len(original):].strip(b"\x00")):
                # The frame decodes to itself plus zeros, which a CRC with no final XOR cannot
                # tell (its register stays 0): the one damage that passes by construction
                # (0x01 bytes before a delimiter; a duplicate makes one only when the CRC ends
                # in 0x00, so the frame ends in a 0x01 code). Decoding decides it here, so the
                # oracle is that exact set. The record arrives whole, its own bytes first (the
                # extra byte reads as an appended field): nothing is lost, nothing to count.
                resyncs -= 1
            else:
                lost.add(i)
                discarded += len(body)
        elif kind == "truncate":
            del body[rnd.randrange(1, len(body)):]
            lost.add(i)
            discarded += len(body)
        elif kind in ("delimiter", "lose_delimiter"):
            # Merges this frame with the next one: this record is lost, the next recovered.
            delimiter = bytes([rnd.randrange(1, 256)]) if kind == "delimiter" else b""
            lost.add(i)
            discarded += len(body) + len(delimiter)
            recovered += 1
        elif kind == "garbage":
            garbage = bytes(rnd.randrange(1, 256) for _ in range(rnd.randrange(1, 40)))
            body = bytearray(garbage) + body                          # glued to this record
            discarded += len(garbage)
            recovered += 1
        resyncs += kind is not None
        out.append(bytes(body) + delimiter)
    return b"".join(out), lost, resyncs, discarded, recovered


def damage_sites(n: int):
    """Distinct records, never adjacent, never the first (bytes before the first delimiter
    are a capture's start-up, tested apart) and never the last (a merge needs a next frame)."""
    return st.dictionaries(st.integers(1, n - 2), st.sampled_from(KINDS), max_size=n // 4) \
        .map(lambda d: {i: k for i, k in d.items() if i - 1 not in d})


def feed_chunked(data: bytes, rnd: random.Random) -> tuple[list, StreamDecoder]:
    decoder = StreamDecoder()
    got, i = [], 0
    while i < len(data):
        step = rnd.randrange(1, 80)
        got += decoder.feed(data[i:i + step])
        i += step
    return got, decoder


N = 60


@settings(max_examples=150)
@given(st.integers(0, 2**32), damage_sites(N))
@example(3481, {1: "flip", 11: "flip", 42: "dup", 7: "garbage", 9: "flip"})   # a frame + 0x00
def test_injected_damage_is_counted_exactly(seed, sites):
    rnd = random.Random(seed)
    frames, records = make_frames(N, seed)
    stream, lost, resyncs, discarded, recovered = inject(frames, sites, rnd)
    expected = [r for i, r in enumerate(records) if i not in lost]

    got, decoder = feed_chunked(stream, rnd)
    s = decoder.stats
    assert got == expected
    assert (s.resyncs, s.bytes_discarded, s.recovered) == (resyncs, discarded, recovered)
    assert s.crc_errors + s.cobs_errors + s.length_errors + s.oversize == resyncs
    assert s.records == len(expected) and s.startup_bytes == 0

    cap = decode_capture(stream)                       # the bulk decoder agrees exactly
    data = [r for r in expected if isinstance(r, P.WrenchRecord)]
    assert (cap.seq % 65536).tolist() == [r.seq for r in data]
    assert cap.wrench_counts.tolist() == [list(r.wrench) for r in data]
    assert [r for _, r in cap.other] == [r for r in expected if not isinstance(r, P.WrenchRecord)]
    b = cap.stats
    assert (b.resyncs, b.bytes_discarded, b.recovered, b.records) == (
        resyncs, discarded, recovered, len(expected))

    # Sequence accounting: the lost data records, no more, no less (those before the first or
    # after the last received one leave no gap to see).
    kept = [i for i, r in enumerate(records) if i not in lost and isinstance(r, P.WrenchRecord)]
    lost_data = sum(isinstance(records[i], P.WrenchRecord) for i in lost
                    if kept and kept[0] < i < kept[-1])
    tracker = SequenceTracker()
    for r in data:
        tracker.update(r.seq, r.time_us)
    assert tracker.lost == cap.lost == lost_data
    assert (tracker.gaps == cap.gaps) and (tracker.gaps >= 1) == (lost_data >= 1)


def reference_decode(stream: bytes) -> list:
    """An independent model of the framing rules: split at 0x00, COBS, CRC, type and exact
    size; for a damaged piece, the shortest suffix that is a complete record."""
    sizes = {int(t): s + 3 for t, s in P.RECORD_SIZES.items()}

    def valid(piece):
        dec = cobs.decode(piece)
        if dec is None or len(dec) < 3 or crc16(dec):
            return None
        return dec[:-2] if sizes.get(dec[0]) == len(piece) else None

    records = []
    pieces = stream.split(b"\x00")[:-1]
    for index, piece in enumerate(pieces):
        if not piece:
            continue
        payload = valid(piece) if len(piece) <= P.MAX_RECORD_SIZE + 64 else None
        if payload is None:
            for length in sorted(set(sizes.values())):
                if length < len(piece) and (payload := valid(piece[-length:])) is not None:
                    break
        if payload is not None:
            records.append(P.parse_payload(payload))
    return records


@given(st.binary(max_size=3000), st.integers(0, 2**32))
def test_random_garbage_decodes_like_the_reference_and_never_raises(garbage, seed):
    got, decoder = feed_chunked(garbage, random.Random(seed))
    assert got == reference_decode(garbage)
    cap = decode_capture(garbage)
    assert len(cap) + len(cap.other) <= len(got)   # repeats of the same seq are dropped
    assert decoder.stats.bytes_received == len(garbage)


@given(st.integers(0, 2**32), st.binary(max_size=400), st.integers(0, 30))
def test_intact_records_after_garbage_all_arrive(seed, garbage, cut):
    """Any garbage, even with zeros in it, and a capture that starts mid-frame: every record
    whose frame is complete and untouched is delivered."""
    frames, records = make_frames(40, seed)
    stream = frames[0][cut:] + garbage + b"".join(frames[1:])
    got, _ = feed_chunked(stream, random.Random(seed))
    for r in records[2:]:                    # the record glued to the garbage is recovered too
        assert r in got
    assert got[-38:] == records[2:]


@given(st.integers(0, 2**32), st.integers(1, 24))
def test_startup_partial_frame_is_not_an_error(seed, cut):
    frames, records = make_frames(10, seed, data_only=True)
    stream = b"".join(frames)[cut:]
    decoder = StreamDecoder()
    got = decoder.feed(stream)
    assert got == records[1:]
    assert decoder.stats.startup_bytes == len(frames[0]) - 1 - cut
    assert decoder.stats.resyncs == 0 and decoder.stats.errors == 0
    cap = decode_capture(stream)
    assert len(cap) == 9 and cap.stats.startup_bytes == decoder.stats.startup_bytes


def test_a_stream_without_delimiters_keeps_memory_bounded():
    decoder = StreamDecoder()
    for _ in range(100):
        assert decoder.feed(b"\x55" * 1000) == []
    assert decoder.pending_bytes <= P.MAX_RECORD_SIZE + 64
    frames, records = make_frames(3, 1, data_only=True)
    got = decoder.feed(b"".join(frames))
    assert got == records                     # the first one recovered from the long tail


@settings(deadline=None)
@given(st.integers(0, 3000), st.integers(1, 700), st.integers(0, 2**32))
def test_bytes_before_the_first_delimiter_count_as_startup_only_up_to_a_frame(noise, chunk,
                                                                                seed):
    """Only the end of one frame can come before the first 0x00: beyond the longest frame,
    bytes without a delimiter (a wrong baud rate) are an error, discarded, not startup bytes.
    The stream decoder, fed in any chunks, and the bulk decoder count alike."""
    rnd = random.Random(seed)
    frames, records = make_frames(4, seed, data_only=True)
    stream = bytes(rnd.randrange(1, 256) for _ in range(noise)) + b"".join(frames)
    decoder = StreamDecoder()
    got = []
    for at in range(0, len(stream), chunk):
        got += decoder.feed(stream[at:at + chunk])
    s = decoder.stats
    assert got == records
    first = noise + len(frames[0]) - 1          # the bytes before the first delimiter
    assert s.startup_bytes == min(first, MAX_FRAME) - (len(frames[0]) - 1)
    assert s.bytes_discarded == max(0, first - MAX_FRAME)
    assert (s.oversize, s.resyncs) == ((1, 1) if first > MAX_FRAME else (0, 0))
    bulk = decode_capture(stream).stats
    fields = ("startup_bytes", "bytes_discarded", "oversize", "resyncs", "records")
    assert [getattr(bulk, f) for f in fields] == [getattr(s, f) for f in fields]


def _feed_in_chunks(stream: bytes, rnd: random.Random, max_chunk: int):
    decoder, got, at = StreamDecoder(), [], 0
    while at < len(stream):
        step = rnd.randint(1, max_chunk)
        got += decoder.feed(stream[at:at + step])
        at += step
    return decoder, got


@settings(deadline=None)
@example(noise=792, lead=3, where=0, max_chunk=400, seed=1)     # the tail counted twice
@example(noise=1000, lead=0, where=5, max_chunk=1, seed=1)      # trimmed, then a COBS error
@given(st.integers(0, 2000), st.integers(0, 5), st.integers(0, 9), st.integers(1, 900),
       st.integers(0, 2**32))
def test_noise_after_the_first_delimiter_counts_alike_in_any_chunking(noise, lead, where,
                                                                      max_chunk, seed):
    """A stretch without 0x00 after the stream is synced is one damaged frame: oversize when
    longer than MAX_FRAME, whatever the chunks that carry it; both decoders count alike."""
    rnd = random.Random(seed)
    frames, records = make_frames(10, seed, data_only=True)
    junk = bytes(rnd.randrange(1, 256) for _ in range(noise))
    stream = (bytes(rnd.randrange(1, 256) for _ in range(lead)) + b"\x00"
              + b"".join(frames[:where]) + junk + b"\x00" + b"".join(frames[where:]))
    decoder, got = _feed_in_chunks(stream, rnd, max_chunk)
    live, bulk = decoder.stats.as_dict(), decode_capture(stream).stats.as_dict()
    assert live == bulk
    assert live["oversize"] == (noise > MAX_FRAME)
    assert live["startup_bytes"] == lead
    assert got[:where] == records[:where] and got[-(10 - where):] == records[where:]


@given(st.integers(0, 2**32), st.integers(1, 3), st.integers(0, 9))
def test_0x01_bytes_before_a_delimiter_are_the_damage_the_crc_cannot_see(seed, k, at):
    """Each is one more zero byte after the frame's CRC, which keeps it 0 (no final XOR): the
    record arrives whole, read as a longer record of its type, and nothing is counted."""
    frames, records = make_frames(10, seed)
    frames[at] = frames[at][:-1] + b"\x01" * k + b"\x00"
    decoder = StreamDecoder()
    assert decoder.feed(b"\x00" + b"".join(frames)) == records
    s = decoder.stats
    assert s.errors == s.resyncs == s.bytes_discarded == 0
    assert decode_capture(b"\x00" + b"".join(frames)).stats.errors == 0


def test_0x01_bytes_after_an_older_minor_versions_record_lose_it_or_make_up_fields():
    """The same damage after a record at an older size (TELEMETRY 48, as 1.0 sent it): one
    byte more is a length no version sends (the record lost), two the current size, read
    with a boot id the device never sent (the old frame's CRC)."""
    old = P.Telemetry(0, 0, 0, 0, 0, (0,) * 6, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, boot_id=None)
    frame = P.encode_record(old, minor=0)
    decoder = StreamDecoder()
    assert decoder.feed(b"\x00" + frame[:-1] + b"\x01\x00") == []
    assert decoder.stats.length_errors == 1
    decoder = StreamDecoder()
    got = decoder.feed(b"\x00" + frame[:-1] + b"\x01\x01\x00")
    assert len(got) == 1 and got[0]._replace(boot_id=None) == old
    assert got[0].boot_id is not None and decoder.stats.errors == 0


def test_sequence_tracker_unwraps_and_counts():
    tracker = SequenceTracker()
    out = [tracker.update(s, t) for s, t in [(65534, 2**32 - 1000), (65535, 2**32 - 10),
                                              (2, 5000), (2, 5000), (3, 6000)]]
    assert out == [(65534, 2**32 - 1000), (65535, 2**32 - 10), (65538, 2**32 + 5000), None,
                   (65539, 2**32 + 6000)]
    assert (tracker.gaps, tracker.lost, tracker.duplicates) == (1, 2, 1)


@settings(max_examples=300)
@given(st.binary(max_size=3000), st.integers(0, 2**32 - 1))
def test_random_bytes_never_break_the_bulk_decoder(blob, seed):
    """Random bytes with the lengths of data frames among them (what made _assemble index an
    empty array): the bulk decoder returns a capture, never raises."""
    rnd = random.Random(seed)
    pieces = [blob]
    for _ in range(rnd.randrange(4)):     # frames of exactly a data record's encoded length
        pieces.append(bytes(rnd.randrange(1, 256) for _ in range(rnd.choice((24, 36)))) + b"\x00")
    data = b"".join(pieces)
    cap = decode_capture(data)
    assert len(cap.seq) == len(cap.status) == len(cap.session) <= data.count(0)
    assert cap.stats.bytes_received == len(data)


def test_random_bytes_the_size_of_data_frames_decode_to_nothing():
    """Regression: frames of a data record's length that fail COBS or CRC, and nothing else."""
    junk = bytes([5, 7] * 12) + b"\x00"            # 24 bytes: a wrench frame's length
    cap = decode_capture(junk * 3)
    # The first frame may be the tail of one sent before we listened: startup bytes.
    assert len(cap) == 0 and cap.stats.crc_errors + cap.stats.cobs_errors == 2
    assert cap.stats.startup_bytes == 24 and cap.sessions == []


def test_a_record_of_unknown_type_is_counted_not_damage():
    """Records of a newer minor version are intact: ignored and counted, not 'damaged'."""
    frames, records = make_frames(20, 5, data_only=True)
    newer = P.frame(bytes([0x42]) + bytes(range(1, 30)))
    stream = b"".join(frames[:10]) + newer + b"".join(frames[10:])
    for stats in (decode_capture(stream).stats, _incremental_stats(stream)):
        assert stats.unknown_types == 1
        assert stats.resyncs == 0 and stats.bytes_discarded == 0 and stats.errors == 0
    assert len(decode_capture(stream)) == 20


def _incremental_stats(stream: bytes):
    decoder = StreamDecoder()
    decoder.feed(stream)
    return decoder.stats


def test_a_restart_without_its_boot_event_is_a_new_session():
    """The counters running backwards (or more missing records than the time could hold) are
    a restart, not a 71-minute clock wrap with 65,000 records missing."""
    tracker = SequenceTracker(max_rate_hz=2000)
    for seq, t in [(500, 1_000_000), (501, 1_002_000)]:
        tracker.update(seq, t)
    assert tracker.update(3, 6_000) == (3, 6_000)                 # back: a new session
    assert (tracker.session, tracker.restarts, tracker.gaps, tracker.lost) == (1, 1, 0, 0)
    assert tracker.update(4, 8_000) == (4, 8_000) and tracker.session == 1
    # Forward in both, but 40,000 records cannot fit into 2 s at 2 kHz: a new session too.
    assert tracker.update(40_005, 2_008_000) == (40_005, 2_008_000) and tracker.session == 2
    # A real gap that fits the time is a gap.
    assert tracker.update(40_105, 2_210_000) == (40_105, 2_210_000)
    assert (tracker.session, tracker.gaps, tracker.lost) == (2, 1, 99)


@given(st.integers(0, 65535), st.integers(0, 2**32 - 1), st.integers(1, 2000),
       st.integers(100, 5000))
def test_a_continuous_stream_is_one_session_across_both_wraps(seq0, t0, rate, n):
    period = 1_000_000 // rate
    seq = (seq0 + np.arange(n)) % 65536
    t = (t0 + period * np.arange(n)) % 2**32
    frames = [P.encode_wrench(int(s), int(u), 0, (0,) * 6) for s, u in zip(seq, t)]
    cap = decode_capture(b"".join(frames), max_rate_hz=rate)
    assert len(cap.sessions) == 1 and cap.gaps == 0
    assert np.array_equal(cap.time_us, t0 + period * np.arange(n))


@settings(deadline=None)
@given(st.lists(st.integers(0, 3), min_size=2, max_size=40), st.integers(0, 2**32 - 1))
def test_a_time_that_stands_still_starts_a_session_in_both_decoders(steps, t0):
    """Records with new sequence numbers and the same device time (a frozen clock, or two
    captures joined): no session may hold a time step of zero, live or offline, and both
    decoders cut at the same records."""
    times = (t0 + 1000 * np.cumsum([0] + steps)) % 2**32
    frames = [P.encode_wrench(i, int(u), 0, (0,) * 6) for i, u in enumerate(times)]
    cap = decode_capture(b"".join(frames), max_rate_hz=1000)
    tracker = SequenceTracker(max_rate_hz=1000)
    live = []
    for i, u in enumerate(times):
        tracker.update(i, int(u))
        live.append(tracker.session)
    assert cap.session.tolist() == live
    assert live[-1] == steps.count(0)
    for rows in cap.sessions:
        assert (np.diff(cap.time_us[rows]) > 0).all()


def test_a_frame_with_a_crc_and_no_payload_is_counted_not_read():
    """Two bytes that are the CRC of nothing pass the CRC; there is no record type to read."""
    empty = cobs.encode(crc16(b"").to_bytes(2, "big")) + b"\x00"
    frames, records = make_frames(3, 1)
    decoder = StreamDecoder()
    got = decoder.feed(frames[0] + empty + frames[1] + frames[2])
    assert got == records
    assert decoder.stats.resyncs == 1 and decoder.stats.records == 3
    cap = decode_capture(frames[0] + empty + frames[1] + frames[2])
    assert cap.stats.resyncs == 1 and cap.stats.records == 3
