"""A calibration's per-joint curves, tabulated as the board holds them (``docs/calibration.md``).

Two corrections are smooth curves in a joint's own angle:

- ``nonlinear_spring`` (torque side): the spring's torque beyond its rate,
  s(q) = k q (p1 (|u| - 3/4) + p2 (u^2 - 3/5)), u = q / 0.5 rad: the diagnosis's term with its
  straight-line part removed (that part belongs to the rate, ``stiffness_mismatch``);
- ``encoder_periodic_error`` (angle side): the magnet's error over the shaft turn,
  e(q) = sum_h a_h sin(h q) + b_h (cos(h q) - 1), h = 1..4, zero at the rest angle where the
  encoders were zeroed; the link's angle is the encoder's minus e.

The encoder error is a function of the count angle q = x * count (x: the signed count from
the zero, what the board has); the spring's curve is taken at the link's angle as far as the
count gives it, q - offset - e(q) (not the backlash's half play: that depends on the direction
of motion). So each depends on one integer per joint. The board evaluates
neither a sine nor a polynomial per sample: :func:`curve_tables` tabulates them per joint at
knots ``KNOT_COUNTS`` counts apart spanning the joint box (the rows of the firmware's coarse
trig tables), as int16, and both the board and :func:`interpolate` here interpolate linearly
between the knots, held at the end knots outside. The Python calibrated model uses exactly
these tables, so host and board compute the same curve.

The tables: ``angle`` is e in units of 2^-``ANGLE_SHIFT`` rad; ``torque`` is the whole joint
torque the curves add, s(q) - k * rate_ratio * e(q) (the encoder error's torque through the
spring rate, folded in so that the board adds one interpolated integer to its torque sum), in
units of 2^-``TORQUE_SHIFT`` N*m.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.core.errors import UserError
from delta6.core.model import ENCODER_COUNT_RAD

#: Reference deflection of the spring curve, rad (its coefficients are the extra torque
#: there as a fraction of the nominal torque); the diagnosis's ``NONLINEAR_REF_RAD``.
SPRING_REF_RAD = 0.5
#: The straight-line parts taken out of the |u| and u^2 columns (their least-squares slopes
#: for u uniform in [-1, 1]); the diagnosis's ``NONLINEAR_STRAIGHT_PART``.
SPRING_STRAIGHT_PART = (0.75, 0.6)
#: Harmonics of a shaft turn in the encoder curve; the diagnosis's ``ENCODER_HARMONICS``.
ENCODER_HARMONICS = (1, 2, 3, 4)
#: Knot spacing, counts (a power of two: the board indexes by a shift); the firmware's
#: ``kTableStep``, so the knots are the rows of its coarse trig tables.
KNOT_SHIFT = 6
KNOT_COUNTS = 1 << KNOT_SHIFT
#: Fixed-point units of the tables: 2^-19 rad (+-0.0625 rad), 2^-16 N*m (+-0.5 N*m).
ANGLE_SHIFT = 19
TORQUE_SHIFT = 16
INT16_MAX = 32767


class CurveRangeError(UserError):
    """A curve the board's int16 tables cannot hold."""


def spring_features(q: np.ndarray, k) -> np.ndarray:
    """(..., 6, 2): the spring curve per unit of each coefficient at angles q (..., 6), N*m."""
    u = q / SPRING_REF_RAD
    tau = np.asarray(k, dtype=float) * q
    lin_abs, lin_sq = SPRING_STRAIGHT_PART
    return np.stack([tau * (np.abs(u) - lin_abs), tau * (u ** 2 - lin_sq)], axis=-1)


def encoder_features(q: np.ndarray) -> np.ndarray:
    """(..., 2H): the encoder error per unit of each coefficient (sin, cos of each harmonic)."""
    return np.stack([f for h in ENCODER_HARMONICS
                     for f in (np.sin(h * q), np.cos(h * q) - 1.0)], axis=-1)


def spring_torque(q: np.ndarray, k, coef: np.ndarray) -> np.ndarray:
    """The spring curve s(q) (..., 6), N*m, for coefficients (6, 2)."""
    return np.einsum("...jc,jc->...j", spring_features(q, k), np.asarray(coef, dtype=float))


def encoder_error(q: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """The encoder error e(q) (..., 6), rad, for coefficients (6, 2H)."""
    return np.einsum("...jc,jc->...j", encoder_features(q), np.asarray(coef, dtype=float))


def limit_counts(design) -> int:
    """Largest count n with n * count <= the joint limit: the firmware solver's box (codegen
    writes this into the design header) and the span of the curve tables."""
    n = int(design.joint_limit_rad / ENCODER_COUNT_RAD)
    while (n + 1) * ENCODER_COUNT_RAD <= design.joint_limit_rad:
        n += 1
    while n * ENCODER_COUNT_RAD > design.joint_limit_rad:
        n -= 1
    return n


def knot_counts(design) -> np.ndarray:
    """The knots (counts): from -origin (the firmware's table origin, a multiple of the
    spacing at or beyond the box) in steps of ``KNOT_COUNTS`` to the first beyond the box's
    upper end, so that every count in the box lies between two knots."""
    n_lim = limit_counts(design)
    origin = -(-n_lim // KNOT_COUNTS) * KNOT_COUNTS
    last = (n_lim + origin) // KNOT_COUNTS + 1
    return np.arange(last + 1) * KNOT_COUNTS - origin


@dataclass(frozen=True)
class CurveTables:
    """Per joint, int16 at the knots (``knots``, counts); None: the curve is absent."""

    knots: np.ndarray                  # (N,) counts
    angle: np.ndarray | None           # (6, N) e, 2^-ANGLE_SHIFT rad (None: all zero)
    torque: np.ndarray                 # (6, N) s - k ratio e, 2^-TORQUE_SHIFT N*m

    @property
    def origin(self) -> int:
        return int(-self.knots[0])


#: The tables' ranges: the largest encoder error (rad) and curve torque (N*m) they hold.
ANGLE_RANGE_RAD = INT16_MAX * 2.0 ** -ANGLE_SHIFT
TORQUE_RANGE_NM = INT16_MAX * 2.0 ** -TORQUE_SHIFT


def _quantize(values: np.ndarray, shift: int, what: str, saturate: bool) -> np.ndarray:
    q = np.round(values * 2.0 ** shift)
    if np.any(np.abs(q) > INT16_MAX) and not saturate:
        raise CurveRangeError(f"{what} reaches {np.abs(values).max():.4g} at the table's knots "
                              f"(the joint box and the knot beyond each end); the board's "
                              f"table holds at most {INT16_MAX / 2.0 ** shift:.4g}")
    return np.clip(q, -INT16_MAX, INT16_MAX).astype(np.int16)


@dataclass(frozen=True)
class CurveValues:
    """The curves at the knots before rounding to the tables' units (rad, N*m), (6, N) each;
    the torque split into its parts, so that a fit can tell which curve overflows."""

    knots: np.ndarray
    angle: np.ndarray            # e
    spring: np.ndarray           # s at the link's angle
    encoder_torque: np.ndarray   # - k ratio e

    @property
    def torque(self) -> np.ndarray:
        return self.spring + self.encoder_torque


def curve_values(design, cal) -> CurveValues:
    """The tables' contents before rounding; the spring and the encoder's torque are taken at
    the angle table's rounded e (held at its range), as the board has it."""
    knots = knot_counts(design)
    q = knots[:, None] * ENCODER_COUNT_RAD * np.ones(6)          # (N, 6)
    angle = encoder_error(q, np.asarray(cal.encoder_periodic_rad, dtype=float))
    error = _quantize(angle, ANGLE_SHIFT, "", True).astype(float) * 2.0 ** -ANGLE_SHIFT
    # The spring bends with the link: its curve at the link's angle as far as it is a function
    # of the count (the offset and the encoder error; not the backlash's direction).
    spring = spring_torque(q - np.asarray(cal.offset_rad, dtype=float) - error, design.k,
                           np.asarray(cal.spring_curvature, dtype=float))
    # The encoder error's torque through the rate, from the tabulated error itself.
    encoder_torque = -design.k * np.asarray(cal.rate_ratio, dtype=float) * error
    return CurveValues(knots, angle.T, spring.T, encoder_torque.T)


def curve_tables(design, cal, saturate: bool = False) -> CurveTables | None:
    """The board's tables for ``cal`` on ``design``. A curve is what its table holds: a table
    that rounds to zero everywhere is no table (``angle`` None), and a calibration whose tables
    are all zero has no curves (None), so the model, the board and its rating agree.
    ``saturate``: hold a value beyond a table's range at the range instead of refusing it
    (a fit's iterates; the fit leaves such a curve out, ``delta6.calibration.families``)."""
    if not np.any(cal.spring_curvature) and not np.any(cal.encoder_periodic_rad):
        return None
    v = curve_values(design, cal)
    angle = _quantize(v.angle, ANGLE_SHIFT, "the encoder curve (angle.periodic_rad), rad,",
                      saturate)
    torque = _quantize(v.torque, TORQUE_SHIFT, "the curves' joint torque, N*m,", saturate)
    if not np.any(angle) and not np.any(torque):
        return None
    return CurveTables(knots=v.knots, angle=angle if np.any(angle) else None, torque=torque)


def has_curves(design, cal) -> bool:
    """Whether the board needs the curve tables for ``cal`` (their tables are not all zero)."""
    return curve_tables(design, cal, saturate=True) is not None


def interpolate(table: np.ndarray, knots: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The table (6, N) at signed counts (n, 6), linear between the knots, held at the end
    knots outside, in the table's units; exactly what the board computes:
    (t_i 2^s + (t_(i+1) - t_i) l) 2^-s, with i = the knot at or below and l = the counts
    beyond it (0..2^s)."""
    x = np.clip(np.asarray(counts, dtype=np.int64), knots[0], knots[-1]) - knots[0]
    i = np.minimum(x >> KNOT_SHIFT, len(knots) - 2)
    l = x - (i << KNOT_SHIFT)
    t = np.asarray(table, dtype=np.int64)
    rows = np.arange(6)
    lo, hi = t[rows, i], t[rows, i + 1]
    return ((lo << KNOT_SHIFT) + (hi - lo) * l).astype(float) * 2.0 ** -KNOT_SHIFT
