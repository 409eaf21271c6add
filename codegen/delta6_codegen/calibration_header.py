"""Render firmware/include/generated/delta6_calibration.h: a unit's calibration for the firmware.

``calibration_constants(design, calibration)`` computes the fields of
``delta6::CalibrationConstants`` (firmware/lib/delta6_core/src/delta6_calibrated.h) in double
precision and rounds them once to float32, in the struct's order; the header and the native
tests use the same numbers. The output is a pure function of its inputs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from delta6.core.calibration import Calibration
from delta6.core.design import Design
from delta6.core.model import NOMINAL_PHI

from .design_header import c_float, c_string
from .solver_constants import f32, solver_constants

#: Must equal delta6::kCalibrationConstantsVersion, kMaxPlayRadii, kMaxSignSpeeds.
CALIBRATION_VERSION = 1
MAX_RADII = 4
MAX_SPEEDS = 4
COMMAND = "delta6 codegen"


@dataclass(frozen=True)
class CalibrationConstants:
    """The struct's fields in order (floats already rounded to float32)."""

    offset: tuple
    half_play: tuple
    direction_half: int
    direction_scale: float
    rate: tuple
    radii: int
    radius: tuple
    hysteresis: tuple          # 6 rows of MAX_RADII
    speed_tau: float
    speeds: int
    inv_speed: tuple
    sign: tuple                # 6 rows of MAX_SPEEDS
    viscous: tuple
    presliding: tuple
    ux: tuple
    uy: tuple
    d: tuple
    la_scale: tuple
    rest: tuple
    lb_sq: tuple
    half_dlb_sq: tuple
    elbow: tuple
    gimbal: tuple
    tilt: float
    c: float
    min_det: float


FIELDS = tuple(CalibrationConstants.__dataclass_fields__)


def _f(values) -> tuple:
    return tuple(f32(v) for v in np.ravel(values))


def _padded(rows: np.ndarray, width: int) -> tuple:
    out = np.zeros((rows.shape[0], width))
    out[:, :rows.shape[1]] = rows
    return tuple(_f(row) for row in out)


def calibration_constants(design: Design, cal: Calibration) -> CalibrationConstants:
    """The firmware's constants for ``cal`` (checked against ``design``)."""
    cal.check_design(design)
    radii = np.asarray(cal.hysteresis_radii_counts, dtype=float)
    speeds = np.asarray(cal.friction_speeds_rad_s, dtype=float)
    if len(radii) > MAX_RADII or len(speeds) > MAX_SPEEDS:
        raise ValueError(f"the firmware takes at most {MAX_RADII} play radii and {MAX_SPEEDS} "
                         "sign speeds")
    mm = 1e-3
    a = design.a_mm + cal.delta_a_mm
    b = design.b_mm + cal.delta_b_mm
    la = design.la_mm + cal.delta_la_mm
    lb = (design.lb_mm + cal.delta_lb_mm) * mm
    phi = NOMINAL_PHI + cal.delta_azimuth_rad
    lb_sq = lb ** 2
    sc = solver_constants(design)
    return CalibrationConstants(
        offset=_f(cal.offset_rad), half_play=_f(0.5 * cal.backlash_play_rad),
        direction_half=int(cal.direction_half_counts),
        direction_scale=f32(1.0 / cal.direction_half_counts),
        rate=_f(design.k * cal.rate_ratio),
        radii=len(radii), radius=tuple(int(r) for r in radii) + (1,) * (MAX_RADII - len(radii)),
        hysteresis=_padded(cal.hysteresis_nm / radii, MAX_RADII),
        speed_tau=f32(cal.speed_filter_s), speeds=len(speeds),
        inv_speed=_f(np.concatenate([1.0 / speeds, np.zeros(MAX_SPEEDS - len(speeds))])),
        sign=_padded(cal.friction_sign_nm, MAX_SPEEDS),
        viscous=_f(cal.viscous_nm_s_per_rad), presliding=_f(cal.presliding_nm),
        ux=_f(np.cos(phi)), uy=_f(np.sin(phi)), d=_f((a - b) * mm),
        la_scale=_f(la / design.la_mm), rest=_f(cal.delta_rest_angle_rad),
        lb_sq=_f(lb_sq), half_dlb_sq=_f(0.5 * (lb_sq - lb_sq[0])),
        elbow=_f(cal.elbow_rad_per_nm), gimbal=_f(cal.gimbal_misalignment_rad),
        tilt=f32(cal.tilt_rad_per_nm), c=f32(design.c_mm * mm),
        # The determinant of the trilateration is sqrt(3)/2 times the solver's S for a
        # symmetric geometry: the same guard, well inside what the design check proves.
        min_det=f32(math.sqrt(3.0) / 2.0 * sc.min_area),
    )


def _value(v) -> str:
    if isinstance(v, tuple):
        return "{" + ", ".join(_value(x) for x in v) + "}"
    if isinstance(v, int):
        return str(v)
    return c_float(v)


def render(design: Design, cal: Calibration, design_label: str, calibration_label: str) -> str:
    """The header text; the labels name the design and calibration files in the banner."""
    k = calibration_constants(design, cal)
    command = f"{COMMAND} {design_label} --calibration {calibration_label}"
    lines = [
        "// GENERATED FILE - DO NOT EDIT.",
        f"// Written by `{command}`.",
        "// The firmware applies this unit's calibration when this header sits next to",
        "// delta6_design.h; `delta6 codegen` without --calibration removes it. tests/firmware/",
        "// test_calibrated_native.py fails when the committed header is stale.",
        "#ifndef DELTA6_GENERATED_CALIBRATION_H",
        "#define DELTA6_GENERATED_CALIBRATION_H",
        "",
        "#include <stdint.h>",
        "",
        '#include "delta6_calibrated.h"',
        '#include "delta6_fastmath.h"',
        '#include "generated/delta6_design.h"',
        "",
        "namespace delta6 {",
        "namespace calibration {",
        "",
        f"constexpr char kName[] = {c_string(cal.name)};",
        "// delta6.core.calibration.Calibration.hash32(): which calibration a board applies.",
        f"constexpr uint32_t kHash = 0x{cal.hash32():08X}UL;",
        f"constexpr uint32_t kDesignHash = 0x{cal.design_hash:08X}UL;",
        f"// Corrects: {', '.join(cal.effects) or 'nothing'}.",
        "const CalibrationConstants kCalibrationConstants DELTA6_FLASH = {",
    ]
    for name in FIELDS:
        lines.append(f"    {_value(getattr(k, name))},  // {name}")
    lines += [
        "};",
        "",
        "}  // namespace calibration",
        "}  // namespace delta6",
        "",
        f"static_assert(delta6::kCalibrationConstantsVersion == {CALIBRATION_VERSION},",
        f'              "delta6_calibration.h is older than the firmware: rerun {COMMAND}");',
        f"static_assert(delta6::kMaxPlayRadii == {MAX_RADII} && "
        f"delta6::kMaxSignSpeeds == {MAX_SPEEDS},",
        f'              "delta6_calibration.h was generated for other sizes: rerun {COMMAND}");',
        "static_assert(delta6::calibration::kDesignHash == delta6::design::kHash,",
        '              "delta6_calibration.h was fitted for another design than delta6_design.h");',
        "",
        "#endif  // DELTA6_GENERATED_CALIBRATION_H",
        "",
    ]
    return "\n".join(lines)
