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

from delta6.core import curves
from delta6.core.calibration import Calibration
from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.model import ENCODER_COUNT_RAD, NOMINAL_PHI

from .design_header import GENERATED_MARKER, _table, c_float, c_string
from .solver_constants import TABLE_STEP, _coarse, f32, solver_constants

#: Must equal delta6::kCalibrationConstantsVersion, kMaxPlayRadii, kMaxSignSpeeds,
#: kTorqueShift.
CALIBRATION_VERSION = 6
MAX_RADII = 4
MAX_SPEEDS = 4
#: The largest backlash (the whole play, rad) on a gimbal joint the board's turn of the joint
#: by half of it, to first order, keeps within the 0.01 % FS the board is held to: the
#: first-order turn's error grows with the square of the play (worst against the Python model
#: over ten random calibrations along random paths: 0.0063 % FS at 0.015 rad, 0.0072 with
#: both curves; 0.011 and 0.0125 at 0.02; 0.05 at 0.05; the branches turn to second order:
#: 0.003 % FS at 0.1 rad). A unit with more play (over 0.9 degree) needs a tighter encoder
#: holder.
MAX_GIMBAL_PLAY_RAD = 0.015
TORQUE_SHIFT = 28
COMMAND = "delta6 codegen"
TABLE_NAMES = tuple(f"kTable{j}" for j in range(1, 7))


@dataclass(frozen=True)
class CalibrationConstants:
    """The struct's fields in order (floats rounded to float32, fixed-point coefficients to
    integers); ``tables`` are the six coarse tables the ``table`` pointers point to."""

    kx: tuple
    kw: tuple                  # 6 rows of MAX_RADII
    kd: tuple
    k0: tuple                  # fixed point, as kx
    direction_half: int
    radii: int
    radius: tuple
    speed_tau: float
    speeds: int
    breakpoint: tuple
    slope: tuple               # 6 rows of MAX_SPEEDS + 1
    offset: tuple              # 6 rows of MAX_SPEEDS + 1, fixed point
    speed_limit: tuple         # rad/s per joint (a calibration's 0, no limit: 1e30)
    speed_lead: float          # s: the friction's speed led by its filtered acceleration
    table: tuple               # names of the six tables
    ed: tuple
    eh: tuple
    elbow: tuple
    ux: tuple
    uy: tuple
    d: tuple
    lb_sq: tuple
    half_dlb_sq: tuple
    gimbal: tuple
    tilt: float
    c: float
    min_det: float
    tables: tuple = ()         # six float32 arrays (n, 3), not a struct field


FIELDS = tuple(f for f in CalibrationConstants.__dataclass_fields__ if f != "tables")


class CalibrationRangeError(UserError, ValueError):
    """A calibration the firmware's fixed-point sums or small-angle steps cannot hold (the
    command line's one-line error)."""


#: Must equal delta6::kCalibrationCurvesVersion, kCurveAngleShift, kCurveTorqueShift,
#: kCurveTurnShift.
CURVES_VERSION = 2
TURN_SHIFT = 31
TORQUE_NAMES = tuple(f"kCurveTorque{j}" for j in range(1, 7))
ANGLE_NAMES = tuple(f"kCurveAngle{j}" for j in range(1, 7))


@dataclass(frozen=True)
class CurveConstants:
    """The fields of ``delta6::CurvedCalibrationConstants`` beside ``base``, and the int16
    tables (``delta6.core.curves.curve_tables``: the ones the Python model interpolates)."""

    knots: int
    torque: np.ndarray               # (6, knots) int16
    angle: np.ndarray | None         # (6, knots) int16, or None
    ed: tuple                        # the backlash angle per half count, 2^-TURN_SHIFT rad
    eh: tuple                        # the backlash angle, 2^-TURN_SHIFT rad


def curve_constants(design: Design, cal: Calibration) -> CurveConstants | None:
    """The curve tables for the firmware (None: the calibration has no curve)."""
    tables = curves.curve_tables(design, cal)
    if tables is None:
        return None
    # The knots are the coarse tables' rows and one beyond by construction: the solver's
    # tables are laid out from ``curves.knot_counts`` (``solver_constants``).
    for table in (tables.torque, tables.angle):
        if table is not None and np.any(np.abs(np.diff(table.astype(int), axis=1)) > 32767):
            raise CalibrationRangeError("a curve changes by more than the firmware's int16 "
                                        "step between two knots")
    # The board sums the backlash angle and the encoder error between two knots in int32
    # units of 2^-TURN_SHIFT rad (the rounding, below 2^-32 rad per half count, is far below
    # a float32 angle's).
    eh = 0.5 * cal.backlash_play_rad
    step = 0.0 if tables.angle is None else \
        np.abs(np.diff(tables.angle.astype(int), axis=1)).max() * 2.0 ** -curves.ANGLE_SHIFT
    if np.abs(eh).max() + step >= 2.0 ** (31 - TURN_SHIFT) * (1 - 2.0 ** -20):
        raise CalibrationRangeError("the backlash and the encoder curve's steps exceed the "
                                    "firmware's fixed-point angle range")

    def q(values) -> tuple:
        return tuple(int(round(v * 2.0 ** TURN_SHIFT)) for v in values)

    return CurveConstants(knots=len(tables.knots), torque=tables.torque, angle=tables.angle,
                          ed=q(eh / cal.direction_half_counts), eh=q(eh))


def _f(values) -> tuple:
    return tuple(f32(v) for v in np.ravel(values))


def _q(values) -> tuple:
    return tuple(int(round(v * 2.0 ** TORQUE_SHIFT)) for v in np.ravel(values))


def _padded(rows: np.ndarray, width: int, convert=_f) -> tuple:
    out = np.zeros((rows.shape[0], width))
    out[:, :rows.shape[1]] = rows
    return tuple(convert(row) for row in out)


def calibration_constants(design: Design, cal: Calibration) -> CalibrationConstants:
    """The firmware's constants for ``cal`` (checked against ``design``)."""
    cal.check_design(design)
    radii = np.asarray(cal.hysteresis_radii_counts, dtype=float)
    speeds = np.asarray(cal.friction_speeds_rad_s, dtype=float)
    if len(radii) > MAX_RADII or len(speeds) > MAX_SPEEDS:
        raise CalibrationRangeError(f"the firmware takes at most {MAX_RADII} play radii and "
                                    f"{MAX_SPEEDS} sign speeds")
    wide = np.flatnonzero(np.abs(cal.backlash_play_rad[3:]) > MAX_GIMBAL_PLAY_RAD)
    if wide.size:
        j = int(wide[0]) + 3
        raise CalibrationRangeError(
            f"joint {j + 1}'s backlash, {cal.backlash_play_rad[j]:.4g} rad, is more than the "
            f"board's gimbal step holds to 0.01 % FS ({MAX_GIMBAL_PLAY_RAD} rad): a unit with "
            "that much play needs a tighter encoder holder")
    mm = 1e-3
    a = design.a_mm + cal.delta_a_mm
    b = design.b_mm + cal.delta_b_mm
    la = (design.la_mm + cal.delta_la_mm) * mm
    lb = (design.lb_mm + cal.delta_lb_mm) * mm
    phi = NOMINAL_PHI + cal.delta_azimuth_rad
    lb_sq = lb ** 2
    half = cal.direction_half_counts
    rate = design.k * cal.rate_ratio
    kx = rate * ENCODER_COUNT_RAD
    kw = cal.hysteresis_nm / radii
    kd = (rate * 0.5 * cal.backlash_play_rad + cal.presliding_nm) / half
    k0 = -rate * cal.offset_rad
    # Friction as a piecewise-linear function: on segment k of |v| (k speeds below it) the
    # first k signs are saturated (+-c_s), the others linear (c_s v / V_s).
    order = np.argsort(speeds)
    c = cal.friction_sign_nm[:, order]
    v_sorted = speeds[order]
    slope = np.stack([cal.viscous_nm_s_per_rad + (c[:, k:] / v_sorted[k:]).sum(axis=1)
                      for k in range(len(speeds) + 1)], axis=1)
    offset = np.stack([c[:, :k].sum(axis=1) for k in range(len(speeds) + 1)], axis=1)
    # The int32 sum (count terms, constant, friction offset) must hold its largest value over
    # the joint box and every play state.
    sc = solver_constants(design)
    tables = curves.curve_tables(design, cal)
    curve_nm = 0.0 if tables is None else \
        np.abs(tables.torque).max(axis=1) * 2.0 ** -curves.TORQUE_SHIFT
    worst = (np.abs(kx) * sc.limit_counts + np.abs(kd) * 2 * half
             + (np.abs(kw) * radii).sum(axis=1) + np.abs(k0)
             + np.abs(offset).max(axis=1, initial=0.0) + curve_nm) * 2.0 ** TORQUE_SHIFT
    if np.any(worst >= 2.0 ** 31 - 64):
        j = int(np.argmax(worst))
        spring = float(np.abs(kx[j]) * sc.limit_counts)
        total = float(worst[j]) * 2.0 ** -TORQUE_SHIFT
        cause = ("the design's spring over its joint box alone" if spring >= 0.5 * total
                 else "mostly the calibration's terms")
        raise CalibrationRangeError(
            f"joint {j + 1}'s torque sum can reach {total:.3g} N*m ({cause}: the spring "
            f"{spring:.3g} N*m), beyond the calibrated firmware's fixed-point range of "
            f"{2.0 ** (31 - TORQUE_SHIFT):g} N*m")
    # Each joint's coarse table holds its constant angle corrections, as the solver's tables,
    # and the encoder curve at its knots (the rows; the board adds the part between them).
    rows = sc.branch_table.shape[0]
    coarse = (np.arange(rows) * TABLE_STEP - sc.table_origin) * ENCODER_COUNT_RAD
    coarse = np.repeat(coarse[None, :], 6, axis=0)
    if tables is not None and tables.angle is not None:
        coarse = coarse - tables.angle[:, :rows] * 2.0 ** -curves.ANGLE_SHIFT
    tables = tuple(
        _coarse(coarse[j], la[j], design.theta_offset_rad + cal.delta_rest_angle_rad[j]
                - cal.offset_rad[j]) if j < 3 else _coarse(coarse[j], 1.0, -cal.offset_rad[j])
        for j in range(6))
    return CalibrationConstants(
        kx=_q(kx), kw=_padded(kw, MAX_RADII, _q), kd=_q(kd), k0=_q(k0),
        direction_half=int(half), radii=len(radii),
        radius=tuple(int(r) for r in radii) + (1,) * (MAX_RADII - len(radii)),
        speed_tau=f32(cal.speed_filter_s), speeds=len(speeds),
        breakpoint=_f(np.concatenate([speeds[order], np.full(MAX_SPEEDS - len(speeds), 1e30)])),
        slope=_padded(slope, MAX_SPEEDS + 1), offset=_padded(offset, MAX_SPEEDS + 1, _q),
        speed_limit=_f(np.where(cal.friction_speed_limit_rad_s > 0,
                                cal.friction_speed_limit_rad_s, 1e30)),
        speed_lead=f32(cal.speed_lead_s),
        table=TABLE_NAMES, ed=_f(0.5 * cal.backlash_play_rad / half),
        eh=_f(0.5 * cal.backlash_play_rad),
        elbow=_f(cal.elbow_rad_per_nm),
        ux=_f(np.cos(phi)), uy=_f(np.sin(phi)), d=_f((a - b) * mm),
        lb_sq=_f(lb_sq), half_dlb_sq=_f(0.5 * (lb_sq - lb_sq[0])),
        gimbal=_f(cal.gimbal_misalignment_rad),
        tilt=f32(cal.tilt_rad_per_nm), c=f32(design.c_mm * mm),
        # The determinant of the trilateration is sqrt(3)/2 times the solver's S for a
        # symmetric geometry: the same guard, well inside what the design check proves.
        min_det=f32(math.sqrt(3.0) / 2.0 * sc.min_area),
        tables=tables,
    )


def _value(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, tuple):
        return "{" + ", ".join(_value(x) for x in v) + "}"
    if isinstance(v, int):
        return str(v)
    return c_float(v)


def render(design: Design, cal: Calibration, design_label: str, calibration_label: str,
           command: str | None = None) -> str:
    """The header text; the labels name the design and calibration files in the banner and
    ``command`` the command line that wrote it (default: ``delta6 codegen DESIGN
    --calibration CAL``)."""
    k = calibration_constants(design, cal)
    command = command or f"{COMMAND} {design_label} --calibration {calibration_label}"
    lines = [
        GENERATED_MARKER,
        f"// Written by `{command}`",
        f"// from the calibration file {calibration_label}. The firmware applies this unit's",
        "// calibration when this header sits next to delta6_design.h; `delta6 codegen` without",
        "// --calibration removes it.",
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
        "",
        "// Each joint's coarse table (fastmath::table_cos_sin, rows as the design's): joints",
        "// 1..3 la_i (cos, sin, sum)(theta_offset + rest_i - offset_i + q), joints 4..6",
        "// (cos, sin, sum)(q - offset_j).",
    ]
    for name, table in zip(TABLE_NAMES, k.tables):
        lines += _table(name, table, f"{name}") + [""]
    cv = curve_constants(design, cal)
    fields = [f"    {_value(getattr(k, name))},  // {name}" for name in FIELDS]
    if cv is None:
        lines += ["const CalibrationConstants kCalibrationConstants DELTA6_FLASH = {"]
        lines += fields + ["};"]
    else:
        lines += [
            "// The per-joint curves (delta6.core.curves.curve_tables), one entry per knot",
            f"// x_i = {curves.KNOT_COUNTS} i - table_origin: the joint torque s(x) - k ratio e(x) in",
            f"// 2^-{curves.TORQUE_SHIFT} N*m" + (f"; the encoder error e(x) in 2^-{curves.ANGLE_SHIFT} rad."
                                                   if cv.angle is not None else "."),
        ]
        for names, tables in ((TORQUE_NAMES, cv.torque), (ANGLE_NAMES, cv.angle)):
            if tables is None:
                continue
            for name, row in zip(names, tables):
                lines.append(f"const int16_t {name}[{len(row)}] DELTA6_FLASH = {{"
                             + ", ".join(str(int(v)) for v in row) + "};")
        angle = ", ".join(ANGLE_NAMES) if cv.angle is not None else ", ".join(["nullptr"] * 6)
        lines += ["", "#define DELTA6_CALIBRATION_CURVES 1",
                  "const CurvedCalibrationConstants kCalibrationConstants DELTA6_FLASH = {",
                  "  {"] + ["  " + f for f in fields] + [
                  "  },",
                  f"    {cv.knots},  // knots",
                  f"    {{{', '.join(TORQUE_NAMES)}}},  // torque",
                  f"    {{{angle}}},  // angle",
                  f"    {_value(cv.ed)},  // ed",
                  f"    {_value(cv.eh)},  // eh",
                  "};"]
    lines += [
        "",
        "}  // namespace calibration",
        "}  // namespace delta6",
        "",
    ]
    if cv is not None:
        lines += [
            f"static_assert(delta6::kCalibrationCurvesVersion == {CURVES_VERSION} && "
            f"delta6::kCurveAngleShift == {curves.ANGLE_SHIFT} && "
            f"delta6::kCurveTorqueShift == {curves.TORQUE_SHIFT} && "
            f"delta6::kCurveTurnShift == {TURN_SHIFT},",
            f'              "delta6_calibration.h was generated for other curves: rerun {COMMAND}");',
        ]
    lines += [
        f"static_assert(delta6::kCalibrationConstantsVersion == {CALIBRATION_VERSION},",
        f'              "delta6_calibration.h is older than the firmware: rerun {COMMAND}");',
        f"static_assert(delta6::kMaxPlayRadii == {MAX_RADII} && "
        f"delta6::kMaxSignSpeeds == {MAX_SPEEDS} && delta6::kTorqueShift == {TORQUE_SHIFT},",
        f'              "delta6_calibration.h was generated for other sizes: rerun {COMMAND}");',
        "static_assert(delta6::calibration::kDesignHash == delta6::design::kHash,",
        '              "delta6_calibration.h was fitted for another design than delta6_design.h");',
        "",
        "#endif  // DELTA6_GENERATED_CALIBRATION_H",
        "",
    ]
    return "\n".join(lines)
