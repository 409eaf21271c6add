"""The protocol's tables (delta6.link.protocol) are the specification's: docs/protocol.md's
record, command, status and EEPROM tables say the same, field by field; every record
round-trips through its layout; layouts, structs and dtypes agree."""
from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.link import protocol as P
from delta6.link.layout import Field, Layout

from conftest import ROOT

DOC = (ROOT / "docs" / "protocol.md").read_text(encoding="utf-8")


def section(title_start: str) -> str:
    """The text of the docs section whose heading starts with ``title_start``, up to the next
    heading of the same or a higher level (subsections included)."""
    match = re.search(rf"^(#+) {re.escape(title_start)}.*$", DOC, re.M)
    assert match, f"no section {title_start!r} in docs/protocol.md"
    end = re.compile(rf"^#{{1,{len(match.group(1))}}} ", re.M).search(DOC, match.end())
    return DOC[match.end():end.start() if end else len(DOC)]


def table_rows(text: str) -> list[list[str]]:
    """The cells of a markdown table's body rows (the first table in ``text``)."""
    rows = []
    for line in text.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            rows.append(cells)
        elif rows:
            break
    return [r for r in rows[1:] if not set("".join(r)) <= set("-: ")]


def field_rows(layout: Layout) -> list[tuple[int, str]]:
    return [(layout.offsets[f.name], f.c_type) for f in layout.fields]


def doc_field_rows(text: str, column: int = 1) -> list[tuple[int, str]]:
    """(offset, type) of each row; the type is the leading ``u8``/``6 x i16``/... of a cell."""
    out = []
    for row in table_rows(text):
        cell = row[column]
        if not cell:
            continue
        kind = re.match(r"(\d+ x )?[uif](8|16|32)\b|\d+ x char", cell)
        assert kind, f"no type in {cell!r}"
        out.append((int(row[0]), kind.group(0)))
    return out


@pytest.mark.parametrize("heading, kind", [("0x01 WRENCH", P.RecordType.WRENCH_RAW),
                                           ("0x03 INFO", P.RecordType.INFO),
                                           ("0x06 TELEMETRY", P.RecordType.TELEMETRY),
                                           ("0x07 EVENT", P.RecordType.EVENT)])
def test_record_tables_in_the_docs_are_the_layouts(heading, kind):
    assert doc_field_rows(section(heading)) == field_rows(P.RECORD_LAYOUTS[kind])


def test_ack_and_nack_tables_in_the_docs_are_the_layouts():
    text = section("0x04 ACK")
    assert doc_field_rows(text, 1) == field_rows(P.RECORD_LAYOUTS[P.RecordType.ACK])
    assert doc_field_rows(text, 2) == field_rows(P.RECORD_LAYOUTS[P.RecordType.NACK])
    reasons = table_rows(text.split("| reason |", 1)[1].join(["| reason |", ""]))
    assert {name: int(value) for value, name, _ in reasons} == {
        r.name: int(r) for r in P.NackReason}


def test_record_headings_give_every_type_and_size():
    headings = re.findall(r"^### (.*)$", section("3. Records"), re.M)
    found = {}
    for heading in headings:
        for code, name, size in re.findall(r"0x([0-9A-F]{2}) ([A-Z_]+) \((\d+)", heading):
            found[name] = (int(code, 16), int(size))
        wire = re.search(r"(\d+) on the wire\) and 0x02 WRENCH_RAW \(\d+, (\d+)\)", heading)
        if wire:
            assert int(wire.group(1)) == P.wire_bytes(P.RecordType.WRENCH)
            assert int(wire.group(2)) == P.wire_bytes(P.RecordType.WRENCH_RAW)
    assert found == {t.name: (int(t), P.RECORD_SIZES[t]) for t in P.RecordType}


def test_command_table_in_the_docs_is_the_commands():
    rows = table_rows(section("4. Commands"))
    documented = {}
    for code, name, args, *_ in rows:
        kind = ", ".join(m.group(0) for m in re.finditer(r"(\d+ x )?[uif](8|16|32)\b", args)) or "-"
        documented[name] = (int(code, 16), "" if kind == "-" else kind)
    assert documented == {
        c.name: (int(c), ", ".join(f.c_type for f in layout.fields[2:]))
        for c, layout in P.COMMAND_LAYOUTS.items()}


def test_status_table_in_the_docs_is_the_status_bits():
    rows = table_rows(section("5. Status word"))
    bits = {}
    for bit, name, _ in rows:
        if name == "ENCODER1..6":
            for j in range(6):
                bits[f"ENCODER{j + 1}"] = int(bit.split("..")[0]) + j
        else:
            bits[name] = int(bit)
    assert bits == {s.name: int(s).bit_length() - 1 for s in P.Status}
    assert P.ENCODER_MASK == sum(P.Status[f"ENCODER{j + 1}"] for j in range(6))


def test_event_codes_in_the_docs_are_the_enums():
    rows = {int(r[0]): r[2] for r in table_rows(section("0x07 EVENT"))}
    assert dict((n, int(v)) for v, n in re.findall(r"(\d) ([A-Z_]+)", rows[1])) == {
        e.name: int(e) for e in P.EventCode}
    reasons = re.search(r"rejected \((.*?)\)", rows[2]).group(1)
    rejections = [int(p) for p in P.ConfigProblem if p != P.ConfigProblem.RATE_LOWERED]
    assert [int(n) for n in re.findall(r"(\d) ", reasons)] == rejections
    info = {int(r[0]): r[2] for r in table_rows(section("0x03 INFO"))}
    offset = P.RECORD_LAYOUTS[P.RecordType.INFO].offsets["config_problem"]
    assert f"{int(P.ConfigProblem.RATE_LOWERED)} RATE_LOWERED" in info[offset]


def test_eeprom_table_in_the_docs_is_the_config_layout():
    rows = doc_field_rows(section("9. Configuration in EEPROM"))
    assert rows[:-1] == field_rows(P.CONFIG_LAYOUT)
    assert rows[-1] == (P.CONFIG_LAYOUT.size, "u16")            # the CRC closes the blob
    assert P.CONFIG_BLOB_SIZE == P.CONFIG_LAYOUT.size + P.CRC_SIZE
    text = section("9. Configuration in EEPROM")
    assert f"magic 0x{P.CONFIG_MAGIC:04X}" in text
    assert f"layout version, {P.CONFIG_LAYOUT_VERSION}" in text
    assert f"blob size, {P.CONFIG_BLOB_SIZE}" in text


# --- records through their layouts ---------------------------------------------------------

def _values(field: Field):
    one = {"B": st.integers(0, 255), "b": st.integers(-128, 127), "H": st.integers(0, 0xFFFF),
           "h": st.integers(-32768, 32767), "I": st.integers(0, 2**32 - 1),
           "f": st.floats(width=32, allow_nan=False)}
    if field.code == "s":
        return st.text("abcdefghijklmnopqrstuvwxyz0123456789-_", max_size=field.count - 1)
    if field.is_array:
        return st.tuples(*[one[field.code]] * field.count)
    return one[field.code]


def _record(kind):
    """A strategy for a record tuple of ``kind`` with any field values."""
    cls = {P.RecordType.INFO: P.Info, P.RecordType.ACK: P.Ack, P.RecordType.NACK: P.Nack,
           P.RecordType.TELEMETRY: P.Telemetry, P.RecordType.EVENT: P.Event}[kind]
    layout = P.RECORD_LAYOUTS[kind]
    fields = {f.name: _values(f) for f in layout.fields if f.name in cls._fields}
    if kind == P.RecordType.INFO:
        fields["streaming"] = st.booleans()
    return st.fixed_dictionaries(fields).map(lambda v: cls(**v))


@given(st.sampled_from([t for t in P.RecordType if t not in P.DATA_FRAME_DTYPES]).flatmap(_record))
def test_every_record_round_trips_through_its_layout(record):
    framed = P.encode_record(record)
    payload = P.unframe(framed[:-1])
    assert len(payload) == P.RECORD_SIZES[payload[0]]
    assert P.parse_payload(payload) == record


def test_record_tuples_name_the_layout_fields():
    """parse_payload fills each tuple by the layout's field names: the two lists agree."""
    tuples = {P.RecordType.INFO: P.Info, P.RecordType.ACK: P.Ack, P.RecordType.NACK: P.Nack,
              P.RecordType.TELEMETRY: P.Telemetry, P.RecordType.EVENT: P.Event,
              P.RecordType.WRENCH_RAW: P.WrenchRecord}
    for kind, cls in tuples.items():
        names = [f.name for f in P.RECORD_LAYOUTS[kind].fields]
        assert [n for n in names if n != "type"] == list(cls._fields), kind


@pytest.mark.parametrize("layout", [*P.RECORD_LAYOUTS.values(), *P.COMMAND_LAYOUTS.values(),
                                    P.CONFIG_LAYOUT], ids=lambda layout: layout.name)
def test_offsets_dtype_and_struct_agree(layout):
    """Fields follow each other without gaps; the numpy view of packed bytes reads the values
    struct packed."""
    ends = [layout.offsets[f.name] + layout.dtype()[f.name].itemsize for f in layout.fields]
    assert [layout.offsets[f.name] for f in layout.fields] == [0, *ends[:-1]]
    assert ends[-1] == layout.size == layout.struct.size
    values = {f.name: (tuple(range(1, f.count + 1)) if f.is_array else
                       b"ab" if f.code == "s" else 7) for f in layout.fields}
    packed = layout.pack(**values)
    row = np.frombuffer(packed, layout.dtype())[0]
    for f in layout.fields:
        assert np.array_equal(row[f.name], values[f.name]), f.name
    assert layout.unpack(packed)["type" if "type" in values else "magic"] == 7


def test_pack_names_missing_and_unknown_fields():
    layout = P.RECORD_LAYOUTS[P.RecordType.ACK]
    with pytest.raises(TypeError, match=r"missing fields \['value'\].*unknown fields \['x'\]"):
        layout.pack(type=4, request_id=1, command=2, x=3)
    with pytest.raises(ValueError, match="twice"):
        Layout("BAD", [Field("a", "B"), Field("a", "H")])


def test_the_framing_examples_in_the_docs_are_what_the_encoders_send():
    text = section("2. Framing")
    wire = bytes.fromhex(re.search(r"^wire\s+([0-9a-f ]+?)\s+\(", text, re.M).group(1))
    assert wire == P.encode_wrench(1, 1000, P.Status.TARE_ACTIVE, (1234, -5, 0, 100, -100, 7))
    rate, request, frame = re.search(r"start streaming at (\d+) Hz with request id (\d+): "
                                     r"`([0-9a-f ]+)`", text).groups()
    assert bytes.fromhex(frame) == P.encode_command(P.Command.START, int(request), int(rate))


def test_the_start_examples_use_a_rate_a_board_accepts():
    """README, docs and the Device docstring show ``dev.start(N)``: N must be a rate the
    firmware's START takes at 16 MHz on every image (DELTA6_RATED_HZ: the analytical model's,
    a calibrated unit's, one with curve tables, one with an on-chip residual), or the example
    fails on some board."""
    app = (ROOT / "firmware" / "src" / "app.cpp").read_text(encoding="utf-8")
    assert re.search(r"#define DELTA6_MAX_RATE_HZ \(DELTA6_RATED_HZ \* \(F_CPU / 1000000UL\) "
                     r"/ 16UL\)", app)
    rated = [int(n) for n in re.findall(r"#define DELTA6_RATED_HZ (\d+)UL", app)]
    assert len(rated) == 4
    board_max = min(rated)
    examples = []
    for path in ("README.md", "docs/protocol.md", "host/delta6/link/device.py"):
        examples += [int(n) for n in re.findall(r"dev\.start\((\d+)\)", (ROOT / path).read_text())]
    assert examples and all(0 < n <= board_max for n in examples), (examples, board_max)
