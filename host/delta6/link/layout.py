"""Byte layouts as tables: a record is a list of named fields, and everything else follows.

:mod:`delta6.link.protocol` writes each record, command and the EEPROM configuration blob as a
:class:`Layout`; the offsets, sizes, ``struct`` formats and numpy dtypes come from that one list,
and ``delta6 codegen --wire`` writes the same offsets and sizes into the firmware's header. So
a field is placed in exactly one line of Python.
"""
from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np

#: numpy spelling of the struct codes a layout may use (all little-endian).
_NUMPY = {"B": "u1", "b": "i1", "H": "<u2", "h": "<i2", "I": "<u4", "i": "<i4", "f": "<f4",
          "s": "S"}
#: How docs/protocol.md and the generated header name each struct code.
_TYPE_NAMES = {"B": "u8", "b": "i8", "H": "u16", "h": "i16", "I": "u32", "i": "i32", "f": "f32",
               "s": "char"}


class Field(NamedTuple):
    """``count`` elements of one struct code; for ``s``, a NUL-padded byte string of ``count``."""

    name: str
    code: str
    count: int = 1

    @property
    def fmt(self) -> str:
        return f"{self.count}{self.code}" if self.count != 1 or self.code == "s" else self.code

    @property
    def is_array(self) -> bool:
        return self.count != 1 and self.code != "s"

    @property
    def c_type(self) -> str:
        """The field's type as docs/protocol.md writes it: ``u16``, ``6 x i16``, ``24 x char``."""
        one = _TYPE_NAMES[self.code]
        return f"{self.count} x {one}" if self.count != 1 or self.code == "s" else one


class Layout:
    """Fields packed little-endian with no padding, in order."""

    def __init__(self, name: str, fields: list[Field]):
        names = [f.name for f in fields]
        if len(set(names)) != len(names):
            raise ValueError(f"{name}: a field name appears twice in {names}")
        for f in fields:
            if f.code not in _NUMPY or f.count < 1:
                raise ValueError(f"{name}.{f.name}: bad field {f}")
        self.name = name
        self.fields = tuple(fields)
        self.struct = struct.Struct("<" + "".join(f.fmt for f in fields))
        self.size = self.struct.size
        self.offsets = {}
        self._slices = []      # (name, first value, value count or None for a scalar)
        offset = value = 0
        for f in fields:
            self.offsets[f.name] = offset
            offset += struct.calcsize("<" + f.fmt)
            width = f.count if f.is_array else 1
            self._slices.append((f.name, value, width if f.is_array else None))
            value += width

    def __repr__(self) -> str:
        return f"Layout({self.name!r}, {self.size} bytes)"

    def field(self, name: str) -> Field:
        return next(f for f in self.fields if f.name == name)

    def unpack(self, buffer, offset: int = 0) -> dict:
        """Field name -> value (a tuple for arrays, bytes for strings) from ``buffer``."""
        values = self.struct.unpack_from(buffer, offset)
        return {name: values[i] if n is None else values[i:i + n] for name, i, n in self._slices}

    def pack(self, **values) -> bytes:
        """The bytes of a record from a value per field (arrays as sequences)."""
        missing = set(self.offsets) - set(values)
        extra = set(values) - set(self.offsets)
        if missing or extra:
            raise TypeError(f"{self.name}: missing fields {sorted(missing)}, "
                            f"unknown fields {sorted(extra)}")
        flat = []
        for f in self.fields:
            if f.is_array:
                flat.extend(values[f.name])
            else:
                flat.append(values[f.name])
        return self.struct.pack(*flat)

    def dtype(self, extra: list[tuple] = ()) -> np.dtype:
        """The layout as a numpy structured dtype (strings as bytes), plus ``extra`` fields."""
        spec = [(f.name, f"S{f.count}") if f.code == "s" else
                (f.name, _NUMPY[f.code], f.count) if f.is_array else (f.name, _NUMPY[f.code])
                for f in self.fields]
        out = np.dtype(spec + list(extra))
        if out.itemsize != self.size + sum(np.dtype(e[1]).itemsize * (e[2] if len(e) > 2 else 1)
                                           for e in extra):
            raise AssertionError(f"{self.name}: dtype and struct disagree")
        return out

    def starts_with(self, other: Layout) -> bool:
        """Whether this layout is ``other`` with fields appended (same names and places)."""
        return self.fields[:len(other.fields)] == other.fields
