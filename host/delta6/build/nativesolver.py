"""The firmware solver compiled natively, driven through ctypes (the shim is firmware/native/solver_shim.cpp).

Each design gets its own library, compiled against the header ``delta6 codegen`` generates
for it (in a temporary include directory). The same library also accepts constants built at
run time from :func:`delta6_codegen.solver_constants`, mirrored in :class:`CConstants`.
"""
from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from delta6.build.nativebuild import FIRMWARE_CORE, FIRMWARE_NATIVE, load_library
from delta6.core.design import Design
from delta6_codegen import SolverConstants, render

CORE = FIRMWARE_CORE
SHIM = FIRMWARE_NATIVE / "solver_shim.cpp"
SOLVER_SOURCES = [CORE / "delta6_solver.cpp", SHIM]

_f6 = ctypes.c_float * 6
_fp = ctypes.POINTER(ctypes.c_float)


class CConstants(ctypes.Structure):
    """Mirror of delta6::SolverConstants (checked against sizeof on the C++ side)."""

    _fields_ = [
        ("d", ctypes.c_float), ("la", ctypes.c_float), ("theta_offset", ctypes.c_float),
        ("lb_sq", ctypes.c_float), ("spring_rate", _f6), ("torque_per_count", _f6),
        ("limit_rad", ctypes.c_float), ("limit_counts", ctypes.c_int16),
        ("table_origin", ctypes.c_int16), ("min_area", ctypes.c_float),
        ("min_height_sq", ctypes.c_float), ("min_lever", ctypes.c_float),
        ("branch_table", _fp), ("joint_table", _fp), ("fine_table", _fp),
    ]


def c_constants(sc: SolverConstants) -> CConstants:
    """A ctypes struct for ``sc``; it keeps its tables alive as attributes."""
    out = CConstants()
    for name, value in sc.scalars.items():
        setattr(out, name, _f6(*value) if isinstance(value, tuple) else value)
    out._tables = []
    for name in ("branch_table", "joint_table", "fine_table"):
        table = np.ascontiguousarray(getattr(sc, name), dtype=np.float32).reshape(-1)
        out._tables.append(table)
        setattr(out, name, table.ctypes.data_as(_fp))
    return out


class NativeSolver:
    """One design's solver library. Methods take batches, shape (n, 6)."""

    def __init__(self, lib: ctypes.CDLL):
        self.lib = lib
        for fn in (lib.d6_solve_counts, lib.d6_solve_radians):
            fn.restype = None
            fn.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_void_p,
                           ctypes.c_void_p]
        lib.d6_constants_size.restype = ctypes.c_size_t
        lib.d6_design_hash.restype = ctypes.c_uint32
        lib.d6_design_limit_counts.restype = ctypes.c_int16
        lib.d6_design_limit_rad.restype = ctypes.c_float
        lib.d6_wrap_count_delta.restype = ctypes.c_int16
        lib.d6_wrap_count_delta.argtypes = [ctypes.c_uint16, ctypes.c_uint16]

    def _call(self, fn, inputs, dtype, constants):
        inputs = np.ascontiguousarray(inputs, dtype=dtype).reshape(-1, 6)
        n = len(inputs)
        wrench = np.full((n, 6), np.nan, dtype=np.float32)
        status = np.full(n, 0xEE, dtype=np.uint8)
        ptr = ctypes.byref(constants) if constants is not None else None
        fn(ptr, n, inputs.ctypes.data, wrench.ctypes.data, status.ctypes.data)
        return wrench, status

    def solve_counts(self, delta, constants: CConstants | None = None):
        return self._call(self.lib.d6_solve_counts, delta, np.int16, constants)

    def solve_radians(self, theta, constants: CConstants | None = None):
        return self._call(self.lib.d6_solve_radians, theta, np.float32, constants)

    def table_trig(self, delta, branch: bool):
        """(cos, sin) from the design's tables for each count in ``delta`` (1-D)."""
        delta = np.ascontiguousarray(delta, dtype=np.int16)
        c = np.empty(len(delta), dtype=np.float32)
        s = np.empty(len(delta), dtype=np.float32)
        self.lib.d6_table_trig(ctypes.c_int(int(branch)), ctypes.c_size_t(len(delta)),
                               ctypes.c_void_p(delta.ctypes.data), ctypes.c_void_p(c.ctypes.data),
                               ctypes.c_void_p(s.ctypes.data))
        return c, s

    def wrap_count_delta(self, raw: int, zero: int) -> int:
        return self.lib.d6_wrap_count_delta(raw, zero)

    def design_name(self) -> str:
        buf = ctypes.create_string_buffer(32)
        self.lib.d6_design_name(buf, ctypes.c_size_t(len(buf)))
        return buf.value.decode()

    def design_full_scale(self) -> np.ndarray:
        out = _f6()
        self.lib.d6_design_full_scale(out)
        return np.array(out[:], dtype=np.float32)


def header_dir(design: Design, base: Path, label: str) -> Path:
    """Write the design's generated header under ``base`` and return the include dir."""
    include = base / design.name / "include"
    (include / "generated").mkdir(parents=True, exist_ok=True)
    (include / "generated" / "delta6_design.h").write_text(render(design, label))
    return include


def native_solver(design: Design, base: Path, label: str, flags=()) -> NativeSolver:
    include = header_dir(design, base, label)
    lib = load_library(f"solver-{design.name}", SOLVER_SOURCES, [include, CORE], tuple(flags))
    return NativeSolver(lib)
