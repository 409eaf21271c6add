"""The firmware's calibrated model compiled natively, driven through ctypes
(firmware/native/calibrated_shim.cpp): the cross-check against ``delta6.core.calibrated``.

One library per design (its generated header); calibrations are passed at run time as a
ctypes mirror of ``delta6::CalibrationConstants`` (its size is checked against the C++ one).
"""
from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from delta6.build.nativebuild import FIRMWARE_CORE, FIRMWARE_NATIVE, load_library
from delta6.build.nativesolver import header_dir
from delta6.core.calibration import Calibration
from delta6.core.design import Design
from delta6_codegen import calibration_constants, render_calibration
from delta6_codegen.calibration_header import FIELDS, MAX_RADII, MAX_SPEEDS, curve_constants

SOURCES = [FIRMWARE_CORE / "delta6_calibrated.cpp", FIRMWARE_CORE / "delta6_solver.cpp",
           FIRMWARE_NATIVE / "calibrated_shim.cpp"]

_F = ctypes.c_float
_I = ctypes.c_int32
_FP = ctypes.POINTER(ctypes.c_float)
_TYPES = {
    "kx": _I * 6, "kw": (_I * MAX_RADII) * 6, "kd": _I * 6, "k0": _I * 6,
    "direction_half": ctypes.c_int16, "radii": ctypes.c_uint8,
    "radius": ctypes.c_int16 * MAX_RADII, "speed_tau": _F, "speeds": ctypes.c_uint8,
    "breakpoint": _F * MAX_SPEEDS, "slope": (_F * (MAX_SPEEDS + 1)) * 6,
    "offset": (_I * (MAX_SPEEDS + 1)) * 6, "speed_limit": _F * 6, "speed_lead": _F,
    "table": _FP * 6, "ed": _F * 6, "eh": _F * 6, "elbow": _F * 3, "ux": _F * 3, "uy": _F * 3, "d": _F * 3,
    "lb_sq": _F * 3, "half_dlb_sq": _F * 3, "gimbal": _F * 3, "tilt": _F, "c": _F,
    "min_det": _F,
}


class CCalibration(ctypes.Structure):
    """Mirror of delta6::CalibrationConstants."""

    _fields_ = [(name, _TYPES[name]) for name in FIELDS]


_I16P = ctypes.POINTER(ctypes.c_int16)


class CCurved(ctypes.Structure):
    """Mirror of delta6::CurvedCalibrationConstants."""

    _fields_ = [("base", CCalibration), ("knots", ctypes.c_uint8), ("torque", _I16P * 6),
                ("angle", _I16P * 6), ("ed", _I * 6), ("eh", _I * 6)]


def _fill(ctype, value):
    if isinstance(value, tuple):
        return ctype(*(_fill(ctype._type_, v) for v in value))
    return value


def c_calibration(design: Design, cal: Calibration) -> CCalibration:
    """A ctypes struct for ``cal``; it keeps its tables alive as an attribute."""
    k = calibration_constants(design, cal)
    out = CCalibration()
    for name in FIELDS:
        if name != "table":
            setattr(out, name, _fill(_TYPES[name], getattr(k, name)))
    out._tables = [np.ascontiguousarray(t, dtype=np.float32).reshape(-1) for t in k.tables]
    out.table = (_FP * 6)(*(t.ctypes.data_as(_FP) for t in out._tables))
    return out


def c_curved(design: Design, cal: Calibration) -> CCurved | None:
    """A ctypes struct for ``cal`` with its curve tables (None: it has no curves)."""
    cv = curve_constants(design, cal)
    if cv is None:
        return None
    out = CCurved()
    base = c_calibration(design, cal)
    out.base = base
    out._base = base      # ctypes copies the struct's bytes; its tables live with the original
    out.knots = cv.knots
    out._curves = [np.ascontiguousarray(t, dtype=np.int16) for t in cv.torque]
    out.torque = (_I16P * 6)(*(t.ctypes.data_as(_I16P) for t in out._curves))
    if cv.angle is not None:
        out._angles = [np.ascontiguousarray(t, dtype=np.int16) for t in cv.angle]
        out.angle = (_I16P * 6)(*(t.ctypes.data_as(_I16P) for t in out._angles))
    out.ed = (_I * 6)(*cv.ed)
    out.eh = (_I * 6)(*cv.eh)
    return out


class NativeCalibrated:
    """The C++ calibrated model of one design; ``run`` keeps the history between calls."""

    def __init__(self, lib: ctypes.CDLL, design: Design, cal: Calibration, period_s: float,
                 use_generated: bool = False):
        self.lib = lib
        lib.d6c_generated.restype = ctypes.c_void_p
        lib.d6c_generated_hash.restype = ctypes.c_uint32
        lib.d6c_constants_size.restype = ctypes.c_size_t
        lib.d6c_state_size.restype = ctypes.c_size_t
        if lib.d6c_constants_size() != ctypes.sizeof(CCalibration):
            raise RuntimeError("CalibrationConstants layout differs between C++ and Python")
        lib.d6c_set_period.argtypes = [ctypes.c_void_p, ctypes.c_float, ctypes.c_void_p]
        lib.d6c_run.argtypes = [ctypes.c_void_p] * 2 + [ctypes.c_size_t] + [ctypes.c_void_p] * 4
        lib.d6c_run_curved.argtypes = lib.d6c_run.argtypes
        lib.d6c_generated_curved.restype = ctypes.c_void_p
        lib.d6c_curved_size.restype = ctypes.c_size_t
        if lib.d6c_curved_size() != ctypes.sizeof(CCurved):
            raise RuntimeError("CurvedCalibrationConstants layout differs between C++ and Python")
        self.constants = c_curved(design, cal)
        self.curved = self.constants is not None
        if not self.curved:
            self.constants = c_calibration(design, cal)
        self._pointer = ctypes.byref(self.constants)
        if use_generated:    # the constants compiled from the generated header instead
            found = lib.d6c_generated_curved() if self.curved else lib.d6c_generated()
            if not found:
                raise RuntimeError("this build has no generated calibration header")
            self._pointer = ctypes.c_void_p(found)
        self.state = ctypes.create_string_buffer(lib.d6c_state_size())
        lib.d6c_reset(self.state)
        # (a curved struct starts with its base)
        lib.d6c_set_period(self._pointer, period_s, self.state)

    def run(self, delta, periods=None) -> tuple[np.ndarray, np.ndarray]:
        """``periods``: per sample, the sample periods since the one before (default 1; more:
        the periods between were lost, as the board's failed reads and missed periods)."""
        delta = np.ascontiguousarray(delta, dtype=np.int16).reshape(-1, 6)
        n = len(delta)
        wrench = np.full((n, 6), np.nan, dtype=np.float32)
        status = np.full(n, 0xEE, dtype=np.uint8)
        run = self.lib.d6c_run_curved if self.curved else self.lib.d6c_run
        if periods is not None:
            periods = np.ascontiguousarray(periods, dtype=np.uint16).reshape(n)
        run(self._pointer, self.state, n, delta.ctypes.data,
            None if periods is None else periods.ctypes.data, wrench.ctypes.data,
            status.ctypes.data)
        return wrench, status


def native_calibrated(design: Design, cal: Calibration, period_s: float, base: Path,
                      label: str = "test", *, generated: bool = False,
                      flags: tuple[str, ...] = ()) -> NativeCalibrated:
    """The C++ model with ``cal`` passed at run time; ``generated``: also compile ``cal``'s
    generated header into the library and run from its constants; ``flags``: extra compiler
    flags (a sanitizer build)."""
    include = header_dir(design, base, label)
    header = include / "generated" / "delta6_calibration.h"
    if generated:
        header.write_text(render_calibration(design, cal, label, "test.toml"))
    elif header.exists():
        header.unlink()
    lib = load_library(f"calibrated-{design.name}", SOURCES, [include, FIRMWARE_CORE], flags)
    return NativeCalibrated(lib, design, cal, period_s, use_generated=generated)
