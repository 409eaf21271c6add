"""Both directions across the language boundary: records the C++ encodes decode in Python
(byte for byte what Python's encoder makes), and commands Python encodes parse in C++."""
from __future__ import annotations

import ctypes
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.link import cobs
from delta6.link import protocol as P
from delta6.link.bulkdecode import decode_capture
from delta6.link.crc import crc16
from delta6.link.decoder import StreamDecoder
from delta6.sim.simdevice import native_library

PARSE_COMMAND = 1          # proto::kParseCommand
PARSE_EMPTY, PARSE_BAD_FRAME, PARSE_BAD_CRC, PARSE_TOO_LONG = 2, 3, 4, 5

u16 = st.integers(0, 0xFFFF)
i16 = st.integers(-32768, 32767)
six_i16 = st.lists(i16, min_size=6, max_size=6)
six_counts = st.lists(st.integers(0, 0xFFFF), min_size=6, max_size=6)
data_records = st.tuples(u16, st.integers(0, 2**32 - 1), u16, six_i16,
                         st.one_of(st.none(), six_counts))


@pytest.fixture(scope="module")
def lib():
    return native_library()


def cpp_data_frame(lib, seq, time_us, status, wrench, counts) -> bytes:
    out = ctypes.create_string_buffer(64)
    w = (ctypes.c_int16 * 6)(*wrench)
    c = (ctypes.c_uint16 * 6)(*counts) if counts is not None else None
    n = lib.d6_encode_data(out, seq, time_us, status, w, c)
    return out.raw[:n]


@given(data_records)
def test_cpp_records_equal_python_records_byte_for_byte(lib, record):
    frame = cpp_data_frame(lib, *record)
    assert frame == P.encode_wrench(*record)
    kind = P.RecordType.WRENCH_RAW if record[4] is not None else P.RecordType.WRENCH
    assert len(frame) == P.wire_bytes(kind)


@given(st.lists(data_records, min_size=1, max_size=30), st.integers(1, 64))
def test_cpp_records_decode_in_python_incremental_and_bulk(lib, records, chunk):
    stream = b"".join(cpp_data_frame(lib, *r) for r in records)
    decoder = StreamDecoder()
    got = []
    for i in range(0, len(stream), chunk):
        got += decoder.feed(stream[i:i + chunk])
    expected = [P.WrenchRecord(s, t, st_, tuple(w), tuple(c) if c is not None else None)
                for s, t, st_, w, c in records]
    assert got == expected
    assert decoder.stats.errors == 0 and decoder.stats.resyncs == 0
    cap = decode_capture(stream)
    # The bulk decoder keeps stream order and drops repeats of the previous record (the same
    # sequence number and time: the same record again).
    keep = [i for i, r in enumerate(records) if i == 0 or r[:2] != records[i - 1][:2]]
    assert cap.wrench_counts.tolist() == [list(records[i][3]) for i in keep]
    assert (cap.seq % 65536).tolist() == [records[i][0] for i in keep]
    assert (cap.time_us % 2**32).tolist() == [records[i][1] for i in keep]
    assert cap.status.tolist() == [records[i][2] for i in keep]
    assert cap.counts.tolist() == [list(records[i][4]) if records[i][4] is not None
                                   else [-1] * 6 for i in keep]


def cpp_parse(lib, data: bytes) -> list[tuple]:
    rows = ctypes.create_string_buffer(32 * 64)
    n = lib.d6_parse_commands(data, len(data), rows, 64)
    out = []
    for k in range(n):
        row = rows.raw[32 * k:32 * (k + 1)]
        if row[0] == PARSE_COMMAND:
            out.append((row[0], row[1], row[2], row[4:4 + row[3] - 2]))
        else:
            out.append((row[0],))
    return out


def command_with_args():
    kinds = {"B": st.integers(0, 255), "H": u16, "f": st.floats(width=32)}

    def build(command):
        args = [kinds[f.code] for f in P.COMMAND_LAYOUTS[command].fields[2:]
                for _ in range(f.count)]
        return st.tuples(st.just(command), st.integers(0, 255),
                         st.tuples(*args).map(list))
    return st.sampled_from(list(P.Command)).flatmap(build)


@given(st.lists(command_with_args(), min_size=1, max_size=8))
def test_python_commands_parse_in_cpp(lib, commands):
    stream = b"".join(P.encode_command(c, r, *a) for c, r, a in commands)
    parsed = cpp_parse(lib, stream)
    assert parsed == [(PARSE_COMMAND, int(c), r, struct.pack("<" + P.COMMAND_ARGS[c], *a))
                      for c, r, a in commands]


def reference_parse(piece: bytes) -> tuple:
    """What the C++ parser must report for one delimited piece (the model of its contract)."""
    if not piece:
        return (PARSE_EMPTY,)
    if len(piece) > P.COMMAND_BUFFER:
        return (PARSE_TOO_LONG,)
    decoded = cobs.decode(piece)
    if decoded is None or len(decoded) < 4:
        return (PARSE_BAD_FRAME,)
    if crc16(decoded):
        return (PARSE_BAD_CRC,)
    return (PARSE_COMMAND, decoded[0], decoded[1], decoded[2:-2])


@given(st.lists(st.one_of(st.binary(max_size=60), command_with_args().map(
    lambda c: P.encode_command(c[0], c[1], *c[2])[:-1])), max_size=10), st.binary(max_size=40))
def test_cpp_parser_matches_its_reference_on_any_bytes(lib, pieces, tail):
    """Garbage, commands and garbage glued to commands: every delimited piece is classified as
    the reference says, and an unfinished tail yields nothing."""
    stream = b"".join(p + b"\x00" for p in pieces) + tail.replace(b"\x00", b"")
    expected = [reference_parse(p) for p in stream.split(b"\x00")[:-1]]
    assert cpp_parse(lib, stream) == expected


def test_cpp_parser_reports_each_failure_kind(lib):
    good = P.encode_command(P.Command.PING, 3)
    flipped = bytearray(good)
    flipped[2] ^= 0x01
    assert cpp_parse(lib, b"\x00") == [(PARSE_EMPTY,)]
    assert cpp_parse(lib, bytes(flipped)) == [(PARSE_BAD_CRC,)]
    assert cpp_parse(lib, b"\x05\x01\x00") == [(PARSE_BAD_FRAME,)]       # code runs past end
    assert cpp_parse(lib, b"\x11" * 40 + b"\x00" + good) == [(PARSE_TOO_LONG,),
                                                              (PARSE_COMMAND, P.Command.PING, 3, b"")]


def test_sim_device_records_have_exact_sizes():
    """Every frame the firmware core sends has exactly its type's documented size."""
    from delta6.sim.simdevice import SimulatedDevice
    sim = SimulatedDevice(rate_hz=1000)
    for cmd, args in [(P.Command.START, (1000,)), (P.Command.GET_TELEMETRY, ()),
                      (P.Command.SET_MODE, (2,)), (P.Command.PING, ()), (P.Command.TARE, (0,))]:
        sim.write(P.encode_command(cmd, 1 + int(cmd) % 200, *args))
        sim.advance(0.05)
    frames = sim.read().split(b"\x00")[:-1]
    sizes = {}
    for f in frames:
        payload = P.unframe(f)
        assert payload is not None
        sizes.setdefault(payload[0], set()).add(len(payload))
    assert sizes == {int(t): {P.RECORD_SIZES[t]} for t in P.RecordType}
    sim.close()


def test_config_blob_is_protected_by_its_crc(lib):
    blob = ctypes.create_string_buffer(P.CONFIG_BLOB_SIZE)
    lib.d6_encode_config((ctypes.c_uint16 * 3)(500, P.Mode.WRENCH_RAW, 1),
                         (ctypes.c_float * 6)(*[0.25] * 6),
                         (ctypes.c_uint16 * 6)(1, 2, 3, 4, 5, 6),
                         (ctypes.c_float * 7)(20.0, 0.0, 0.0, 0.125, 0.0, 0.5, -1.5),
                         (ctypes.c_uint16 * 6)(100, 0, 3000, 7, 8, 32767), 0x535534AF, blob)
    raw = blob.raw
    assert raw[:2] == b"D6"                   # the magic reads "D6" in a hex dump
    assert P.crc16(raw) == 0                  # CRC big-endian at the end, like frames
    assert P.CONFIG_LAYOUT.unpack(raw) == {
        "magic": P.CONFIG_MAGIC, "layout": P.CONFIG_LAYOUT_VERSION, "size": P.CONFIG_BLOB_SIZE,
        "design_hash": 0x535534AF, "rate_hz": 500, "mode": P.Mode.WRENCH_RAW, "tare_active": 1,
        "tare": (0.25,) * 6, "zero_counts": (1, 2, 3, 4, 5, 6), "filter_hz": 20.0,
        "tool_translation": (0.0, 0.0, 0.125), "tool_rpy": (0.0, 0.5, -1.5),
        "limits": (100, 0, 3000, 7, 8, 32767)}
    assert len(raw) == P.CONFIG_LAYOUT.size + P.CRC_SIZE


def test_cpp_sizes_of_every_type_byte_are_the_tables(lib):
    """The core's recordSize and commandSize (switches over the generated constants) know
    exactly the record types and commands of delta6.link.protocol, with their sizes."""
    for t in range(256):
        assert lib.d6_record_size(t) == P.RECORD_SIZES.get(t, 0), hex(t)
        assert lib.d6_command_size(t) == P.COMMAND_SIZES.get(t, 0), hex(t)


@given(st.sampled_from([0, 9600, 115_200, 250_000, 500_000, 1_000_000, 2_000_000])
       | st.integers(1, 4_000_000), st.sampled_from(list(P.Mode)))
def test_cpp_link_limit_is_the_python_one(baud, mode):
    """Both ends compute the highest rate a link carries in integers, the same way."""
    from delta6.sim.simdevice import NativeCore
    core = NativeCore(design_name="x", design_hash=1, full_scale=[1.0] * 6,
                      joint_limit_rad=0.5, joint_limit_counts=0, baud=baud, max_rate_hz=2000,
                      default_rate_hz=100, zero_counts=[0] * 6)
    try:
        assert core.link_limit(mode) == P.link_rate_limit(baud, mode)
    finally:
        core.close()
