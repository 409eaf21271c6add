"""The numbers the firmware solver needs for one design (delta6::SolverConstants).

Computed in double precision from the design and rounded once to float32, so the generated
header, the native ctypes tests and the AVR image all use identical values. The field order
and meaning match ``struct SolverConstants`` in firmware/lib/delta6_core/src/delta6_solver.h.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from delta6.core.curves import KNOT_COUNTS, knot_counts, limit_counts
from delta6.core.design import Design, DesignError
from delta6.core.model import ENCODER_COUNT_RAD
from delta6.core.workspace import MIN_HEIGHT_FRACTION, MIN_LEVER_FRACTION

#: Must equal delta6::kTableStep and kSolverConstantsVersion (the header static_asserts it).
#: The coarse tables' rows are the curve tables' knots (``delta6.core.curves``) but the last.
TABLE_STEP = KNOT_COUNTS
CONSTANTS_VERSION = 1
#: The solver's fault thresholds sit this many times inside what the design check proves
#: for the whole joint box, so they never trip inside the box of a valid design.
GUARD_FACTOR = 5.0


@dataclass(frozen=True)
class SolverConstants:
    d: float                    # a - b, m
    la: float                   # m
    theta_offset: float         # rad
    lb_sq: float                # m^2
    spring_rate: tuple          # 6 x N*m/rad
    torque_per_count: tuple     # 6 x N*m per count
    limit_rad: float            # rad, largest float32 <= the joint limit
    limit_counts: int           # counts, largest n with n * count <= the joint limit
    table_origin: int           # multiple of TABLE_STEP >= limit_counts
    min_area: float             # m^2
    min_height_sq: float        # m^2
    min_lever: float            # m^2
    branch_table: np.ndarray    # float32 (n, 3): la (cos, sin, cos + sin)(off + q)
    joint_table: np.ndarray     # float32 (n, 3): cos q, sin q, cos q + sin q
    fine_table: np.ndarray      # float32 (TABLE_STEP, 3): cos l, sin l - cos l, cos l + sin l

    @property
    def scalars(self) -> dict:
        return {name: getattr(self, name) for name in SCALAR_FIELDS}


SCALAR_FIELDS = ("d", "la", "theta_offset", "lb_sq", "spring_rate", "torque_per_count",
                 "limit_rad", "limit_counts", "table_origin", "min_area", "min_height_sq",
                 "min_lever")


def f32(x: float) -> float:
    """Round to the nearest float32 (returned as a Python float, exactly representable)."""
    return float(np.float32(x))


def f32_at_most(x: float) -> float:
    """The largest float32 not above ``x``: a box test in float32 then agrees exactly with
    the same test in double for every float32 input."""
    v = np.float32(x)
    if float(v) > x:
        v = np.nextafter(v, np.float32(-np.inf), dtype=np.float32)
    return float(v)


def _coarse(angles: np.ndarray, scale: float = 1.0, offset: float = 0.0) -> np.ndarray:
    """Rows (a cos, a sin, a (cos + sin)) of offset + angles: see table_cos_sin."""
    c, s = scale * np.cos(offset + angles), scale * np.sin(offset + angles)
    return np.stack([c, s, c + s], axis=-1).astype(np.float32)


def _fine(angles: np.ndarray) -> np.ndarray:
    """Rows (cos, sin - cos, cos + sin): see table_cos_sin."""
    c, s = np.cos(angles), np.sin(angles)
    return np.stack([c, s - c, c + s], axis=-1).astype(np.float32)


def solver_constants(design: Design) -> SolverConstants:
    """Constants of ``design`` for the firmware solver. Raises DesignError if the solver's
    elimination cannot serve the design (an elbow centre reaching the base axis)."""
    mm = 1e-3
    d = (design.a_mm - design.b_mm) * mm
    la, lb = design.la_mm * mm, design.lb_mm * mm
    off, limit = design.theta_offset_rad, design.joint_limit_rad
    # Smallest radial distance r = a - b + la cos(theta) of an elbow centre over the box.
    # theta stays in (-pi, pi), where cos peaks at 0: its minimum is at an end of the range.
    r_min = d + la * min(math.cos(off - limit), math.cos(off + limit))
    if r_min <= 0.05 * d:
        raise DesignError("la_mm", "the firmware solver needs every elbow centre off the base "
                          f"axis (a - b + la cos(theta) >= 5 % of a - b over the joint box; "
                          f"min is {r_min / mm:.3g} mm)")
    n_lim = limit_counts(design)
    knots = knot_counts(design)
    origin = int(-knots[0])
    coarse = knots[:-1] * ENCODER_COUNT_RAD
    fine = np.arange(TABLE_STEP) * ENCODER_COUNT_RAD
    k = design.k
    return SolverConstants(
        d=f32(d), la=f32(la), theta_offset=f32(off), lb_sq=f32(lb * lb),
        spring_rate=tuple(f32(v) for v in k),
        torque_per_count=tuple(f32(v * ENCODER_COUNT_RAD) for v in k),
        limit_rad=f32_at_most(limit), limit_counts=n_lim, table_origin=origin,
        # S >= 3 r_min^2 over the box; the height and lever bounds are the design check's.
        min_area=f32(3.0 * r_min ** 2 / GUARD_FACTOR),
        min_height_sq=f32((MIN_HEIGHT_FRACTION * lb / GUARD_FACTOR) ** 2),
        min_lever=f32(MIN_LEVER_FRACTION * la * lb / GUARD_FACTOR),
        branch_table=_coarse(coarse, la, off),
        joint_table=_coarse(coarse),
        fine_table=_fine(fine),
    )
