"""Render firmware/lib/delta6_core/src/generated/delta6_wire.h: the wire layout for the C++ core.

Every number of the protocol that both ends share comes from :mod:`delta6.link.protocol` (record
types and field layouts, commands and their sizes, modes, status bits, NACK reasons, event
codes, configuration problems, the EEPROM blob, the link budget) and :mod:`delta6.link.wirescale`
(the LSB steps). The firmware core includes the header and writes none of these numbers
itself. The output depends on nothing else, so it is the same bytes on every machine.
"""
from __future__ import annotations

import enum
import struct

from delta6.link import protocol as P
from delta6.link import wirescale
from delta6.link.layout import Layout

from .design_header import GENERATED_MARKER, c_float

COMMAND = "delta6 codegen --wire"
#: Where the header lives, relative to the repository root.
HEADER_RELPATH = "firmware/lib/delta6_core/src/generated/delta6_wire.h"


def camel(name: str) -> str:
    """``WRENCH_RAW`` or ``design_name`` -> ``WrenchRaw`` / ``DesignName``."""
    return "".join(part.capitalize() for part in name.lower().split("_"))


def _enum(members: type[enum.IntEnum], prefix: str, title: str, hex_width: int = 0,
          ctype: str = "uint8_t") -> list[str]:
    lines = [f"// --- {title} ---"]
    for m in members:
        value = f"0x{int(m):0{hex_width}X}" if hex_width else str(int(m))
        lines.append(f"const {ctype} {prefix}{camel(m.name)} = {value};")
    return lines + [""]


def _offsets(prefix: str, layout: Layout) -> list[str]:
    """``k<Prefix>Off<Field>`` for every field, with its type as a comment."""
    lines = []
    for f in layout.fields:
        lines.append(f"const uint8_t {prefix}Off{camel(f.name)} = {layout.offsets[f.name]};"
                     f"  // {f.c_type}")
        if f.code == "s":
            lines.append(f"const uint8_t {prefix}{camel(f.name)}Bytes = {f.count};"
                         "  // NUL-padded")
    return lines


def _records() -> list[str]:
    lines = ["// --- records (device -> host): type, payload size (type byte included, CRC",
             "// excluded) and the offset of every field (docs/protocol.md section 3) ---"]
    for kind, layout in P.RECORD_LAYOUTS.items():
        name = f"k{camel(kind.name)}"
        lines += ["", f"const uint8_t {name} = 0x{int(kind):02X};",
                  f"const uint8_t {name}Size = {layout.size};", *_offsets(name, layout)]
    size = P.MAX_RECORD_SIZE
    return lines + ["", f"const uint8_t kMaxRecordSize = {size};",
                    "// Bytes on the wire beyond the payload: CRC, one COBS code byte, the "
                    "delimiter.",
                    f"const uint8_t kFrameOverhead = {P.FRAME_OVERHEAD};",
                    f"const uint8_t kMaxFrameBytes = {size + P.FRAME_OVERHEAD};", "",
                    *_size_table("Record", {int(t): n for t, n in P.RECORD_SIZES.items()})]


def _size_table(what: str, sizes: dict[int, int]) -> list[str]:
    """Payload size by type code from the first one (0: no such type), in flash: a switch
    would become a lookup table in the AVR's RAM."""
    first, last = min(sizes), max(sizes)
    values = ", ".join(str(sizes.get(code, 0)) for code in range(first, last + 1))
    return [f"// Payload size of each {what.lower()} type from kFirst{what}Type on (0: none).",
            f"const uint8_t kFirst{what}Type = 0x{first:02X};",
            f"const uint8_t k{what}TypeCount = {last - first + 1};",
            f"const uint8_t k{what}SizeByType[k{what}TypeCount] DELTA6_FLASH = {{{values}}};", ""]


def _commands() -> list[str]:
    lines = ["// --- commands (host -> device): type, request id, arguments; each command's",
             "// exact payload size (docs/protocol.md section 4) ---"]
    for command, layout in P.COMMAND_LAYOUTS.items():
        args = ", ".join(f"{f.c_type} {f.name}" for f in layout.fields[2:])
        name = f"kCmd{camel(command.name)}"
        lines.append(f"const uint8_t {name} = 0x{int(command):02X};")
        lines.append(f"const uint8_t {name}Size = {layout.size};" + (f"  // {args}" if args else ""))
    return lines + [
        "// Types below this are records: a device never answers them (its own output looped",
        "// back must not start an endless exchange).",
        f"const uint8_t kFirstCommand = 0x{P.FIRST_COMMAND_TYPE:02X};",
        f"const uint8_t kLastCommand = 0x{max(P.Command):02X};",
        f"const uint8_t kMaxCommandSize = {max(P.COMMAND_SIZES.values())};",
        "// Receive buffer (encoded bytes): longer command frames are discarded and counted.",
        f"const uint8_t kCommandBuffer = {P.COMMAND_BUFFER};", "",
        *_size_table("Command", {int(c): n for c, n in P.COMMAND_SIZES.items()})]


def _status() -> list[str]:
    lines = ["// --- status word bits (docs/protocol.md section 5) ---"]
    for flag in P.Status:
        lines.append(f"const uint16_t kStatus{camel(flag.name)} = 1u << {int(flag).bit_length() - 1};")
    return lines + [f"const uint16_t kStatusEncoderMask = 0x{P.ENCODER_MASK:04X};", ""]


def _config_blob() -> list[str]:
    layout = P.CONFIG_LAYOUT
    return ["// --- the configuration blob in EEPROM (docs/protocol.md section 9), followed by "
            "its CRC,", "// most significant byte first ---",
            f"const uint16_t kConfigMagic = 0x{P.CONFIG_MAGIC:04X};",
            f"const uint8_t kConfigLayoutVersion = {P.CONFIG_LAYOUT_VERSION};",
            f"const uint16_t kConfigBlobSize = {P.CONFIG_BLOB_SIZE};",
            "// Older layouts the device still loads: each is a prefix of the newest (same",
            "// offsets), its blob shorter; the fields it lacks take the defaults.",
            *[line for v in sorted(P.CONFIG_LAYOUTS) if v != P.CONFIG_LAYOUT_VERSION
              for line in (f"const uint8_t kConfigLayoutV{v} = {v};",
                           f"const uint16_t kConfigBlobSizeV{v} = {P.CONFIG_BLOB_SIZES[v]};")],
            *_offsets("kConfig", layout), ""]


def _scaling() -> list[str]:
    exponents = range(wirescale.MIN_EXPONENT, wirescale.MAX_EXPONENT + 1)
    mantissas = wirescale.MANTISSAS
    return [
        "// --- wrench scaling (docs/protocol.md section 7): LSB = mantissa x 10^exponent, the",
        f"// smallest step whose +-{P.MAX_VALUE} counts cover kHeadroom x full scale ---",
        f"const int8_t kMinExponent = {wirescale.MIN_EXPONENT};",
        f"const int8_t kMaxExponent = {wirescale.MAX_EXPONENT};",
        f"const uint8_t kMantissaCount = {len(mantissas)};",
        "// In flash on the AVR (DELTA6_FLASH): read them with flash::byte and flash::f32.",
        f"const uint8_t kMantissas[kMantissaCount] DELTA6_FLASH = "
        f"{{{', '.join(map(str, mantissas))}}};",
        "// Decades as float literals: the host (delta6.link.wirescale) rounds the same decimals",
        "// to float32, so both ends pick the same step even at exact boundaries.",
        "const float kDecades[kMaxExponent - kMinExponent + 1] DELTA6_FLASH = {",
        "    " + ", ".join(f"1e{e}f" for e in exponents) + "};",
        f"const float kHeadroom = {wirescale.HEADROOM!r}f;",
        "// A wrench value: counts of the LSB; kInvalidValue when the sample has none.",
        f"const int16_t kInvalidValue = {P.INVALID_VALUE};",
        f"const int16_t kMaxValue = {P.MAX_VALUE};",
        "// float(kMaxValue) as IEEE-754 binary32 bits: quantize() compares magnitudes as integers.",
        f"const uint32_t kMaxValueFloatBits = 0x{_float_bits(P.MAX_VALUE):08X}UL;",
        ""]


def _float_bits(x: float) -> int:
    return struct.unpack("<I", struct.pack("<f", x))[0]


def render_wire() -> str:
    """The text of generated/delta6_wire.h."""
    budget = P.LINK_BUDGET
    lines = [
        GENERATED_MARKER,
        f"// Written by `{COMMAND}` from delta6.link.protocol and delta6.link.wirescale",
        "// (host/delta6/link/). Regenerate with that command; tests/firmware/test_codegen.py fails",
        "// when this file is out of date. docs/protocol.md explains every number.",
        "#ifndef DELTA6_GENERATED_WIRE_H",
        "#define DELTA6_GENERATED_WIRE_H",
        "",
        "#include <stdint.h>",
        "",
        "#include \"delta6_flash.h\"",
        "",
        "namespace delta6 {",
        "namespace proto {",
        "",
        f"const uint8_t kVersionMajor = {P.VERSION[0]};",
        f"const uint8_t kVersionMinor = {P.VERSION[1]};",
        "",
        *_records(),
        *_commands(),
        *_enum(P.Mode, "kMode", "stream modes (SET_MODE argument, INFO)"),
        *_status(),
        *_enum(P.NackReason, "kNack", "NACK reasons (docs/protocol.md section 3)"),
        *_enum(P.EventCode, "kEvent", "event codes (EVENT record)"),
        *_enum(P.ConfigProblem, "kConfig",
               "why a stored configuration was rejected (CONFIG_DEFAULTS argument), or "
               "how it was adjusted (INFO only)"),
        *_config_blob(),
        "// --- the tool frames the device accepts (SET_TOOL): |translation| per axis, m, and",
        "// |angle|, rad ---",
        f"const float kMaxToolTranslation = {c_float(P.TOOL_MAX_TRANSLATION_M)};",
        f"const float kMaxToolAngle = {c_float(P.TOOL_MAX_ANGLE_RAD)};",
        "",
        "// --- telemetry ---",
        f"const int16_t kTemperatureUnknown = 0x{P.TEMPERATURE_UNKNOWN:04X};"
        "  // no temperature sensor",
        "",
        *_scaling(),
        f"// --- the link: data records may fill {budget.numerator}/{budget.denominator} of its "
        f"baud / {P.BITS_PER_BYTE} bytes per second, computed",
        "// as baud / kLinkBudgetDivisor x kLinkBudgetNumerator (dividing first: no 32-bit "
        "overflow) ---",
        f"const uint8_t kLinkBudgetNumerator = {budget.numerator};",
        f"const uint16_t kLinkBudgetDivisor = {P.BITS_PER_BYTE * budget.denominator};",
        "",
        "}  // namespace proto",
        "}  // namespace delta6",
        "",
        "#endif  // DELTA6_GENERATED_WIRE_H",
        "",
    ]
    return "\n".join(lines)
