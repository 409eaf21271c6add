"""The calibration's parameter families: for each correctable effect, how the calibrated model's
wrench changes per unit of each of its parameters (columns, linear around the current
calibration) and how a fitted step updates the calibration.

The columns use the diagnosis's per-sample maps of the analytical model (``G``: joint torques
to wrench, ``J = dW/dtheta``, ``dW/d(geometry)``) and the calibrated model's own *causal*
history features (``delta6.core.calibrated``), so what is fitted is exactly what the board
computes. Each family returns columns (n, 6, p) in the units of its parameters.

Each family also says how its parameters read in the diagnosis's term of the same effect
(``term_map``: a linear map onto that term's coefficients), so the fit carries the same
physics as the diagnosis: the term's prior scales (``Term.prior_sd``) regularise the fit, and
the term's plausible limits (``Term.plausibility``) judge the fitted calibration, each
parameter against its own limit.

A family may also hold signs that physics fixes (``constraints``: ``A @ values >= lower``),
which the fit imposes: a passive friction torque opposes the motion at every speed.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from delta6.core import curves, model
from delta6.core.calibrated import JointTerms, counts_from_angles, friction_speed
from delta6.core.calibration import Calibration, CalibrationError, validate
from delta6.core.model import ENCODER_COUNT_RAD
from delta6.diagnosis.data import GapData
from delta6.diagnosis.terms import (
    FRICTION_VELOCITIES_RAD_S,
    HYSTERESIS_RADII,
    SMOOTH_IN_ANGLE_FAMILIES,
    TERMS,
    Term,
    for_design,
    force_rotation,
)
from delta6_codegen.calibration_header import MAX_GIMBAL_PLAY_RAD


@dataclass
class Context:
    data: GapData            # the log with the analytical model's maps
    terms: JointTerms        # the calibrated model's causal features on the log's counts
    cal: Calibration         # the settings the features were computed with

    @property
    def n(self) -> int:
        return len(self.data)


@dataclass(frozen=True)
class Family:
    effect: str
    param_names: tuple[str, ...]
    columns: Callable[[Context], np.ndarray]
    apply: Callable[[Calibration, np.ndarray], Calibration]
    #: The family's parameters as they stand in a calibration (deviation from neutral).
    values: Callable[[Calibration], np.ndarray]
    #: (term width, family width): the parameters as the diagnosis term's coefficients.
    term_map: np.ndarray
    #: The calibration's attributes the family sets.
    fields: tuple[str, ...]
    on_device: bool = True
    #: Linear inequalities on the values, (A, lower): A @ values >= lower (None: no sign fixed).
    constraints: Callable[[Calibration], tuple[np.ndarray, np.ndarray]] | None = None
    #: Whether each parameter is also checked on its own (False: only the family's whole
    #: curve, when the term's limits are on a curve its parameters build together).
    each_parameter: bool = True
    #: The diagnosis's term sized for the design (``terms.for_design``; None: as written).
    sized_term: Term | None = None

    @property
    def term(self) -> Term:
        return self.sized_term if self.sized_term is not None else _TERMS[self.effect]

    @property
    def prior_sd(self) -> tuple[float, ...]:
        """Each parameter's prior scale: the term's, of the coefficient it maps onto."""
        prior = np.asarray(self.term.prior_sd, dtype=float)
        return tuple(float(prior[i]) for i in np.argmax(np.abs(self.term_map), axis=0))

    def plausibility(self, cal: Calibration) -> list[dict]:
        """The fitted parameters against the term's plausible limits (``Term.plausibility``),
        and against the calibration file's own bounds (a check named ``file_bounds``).

        Each parameter is checked on its own (alone in the term's coefficients), and the
        family as a whole: several parameters can map onto one coefficient (two play radii
        near one of the diagnosis's) or onto quantities the term sums (a loop half-width over
        the radii), and large values of opposite signs would cancel in the sum."""
        values = self.values(cal)
        checks = self.term.plausibility(self.term_map @ values)
        for i in np.flatnonzero(values) if self.each_parameter else ():
            for check in self.term.plausibility(self.term_map[:, i] * values[i]):
                same = next(c for c in checks if c["quantity"] == check["quantity"])
                if check["ratio"] > same["ratio"]:
                    same.update(check)
        probe = neutral_like(cal).with_(**{f: getattr(cal, f) for f in self.fields})
        try:
            validate(probe)
        except CalibrationError as exc:
            checks.append({"quantity": f"file_bounds ({exc})", "largest": float("inf"),
                           "limit": 0.0, "ratio": float("inf")})
        return checks

    def implausible(self, cal: Calibration) -> list[dict]:
        return [c for c in self.plausibility(cal) if c["ratio"] > 1.0]


#: The curve families, tabulated per joint on the board.
CURVE_FAMILIES = SMOOTH_IN_ANGLE_FAMILIES


def curve_table_checks(design, cal: Calibration, effect: str) -> list[dict]:
    """A curve family's fitted curve against the board's int16 tables (at the knots: the
    joint box and one knot beyond each end), as ``Family.plausibility``'s checks: the encoder
    error in the angle table, each curve's own joint torque, and the torque table they fill
    together (that check goes to the curve with the larger part of it at its worst knot)."""
    if effect not in CURVE_FAMILIES:
        return []
    v = curves.curve_values(design, cal)
    own = v.spring if effect == "nonlinear_spring" else v.encoder_torque
    other = v.encoder_torque if effect == "nonlinear_spring" else v.spring
    worst = np.unravel_index(np.argmax(np.abs(v.torque)), v.torque.shape)
    both = np.abs(v.torque).max() if abs(own[worst]) >= abs(other[worst]) else 0.0
    checks = [("board_table_torque_nm", max(np.abs(own).max(), both), curves.TORQUE_RANGE_NM)]
    if effect == "encoder_periodic_error":
        checks.append(("board_table_angle_rad", np.abs(v.angle).max(), curves.ANGLE_RANGE_RAD))
    return [{"quantity": q, "largest": float(x), "limit": lim, "ratio": float(x) / lim}
            for q, x, lim in checks]


def without_vanishing_curves(design, cal: Calibration) -> Calibration:
    """``cal`` with each curve whose board table rounds to zero written as zero: it is no
    curve (``curves.curve_tables``), and so the file's hash is that of what the board does."""
    tables = curves.curve_tables(design, cal)
    if tables is None:
        return cal.with_(spring_curvature=np.zeros_like(cal.spring_curvature),
                         encoder_periodic_rad=np.zeros_like(cal.encoder_periodic_rad))
    if tables.angle is None:
        return cal.with_(encoder_periodic_rad=np.zeros_like(cal.encoder_periodic_rad))
    return cal


def _torque(ctx: Context, per_joint: np.ndarray) -> np.ndarray:
    """Extra joint torques per feature (n, 6, m) -> wrench columns (n, 6, 6 m), joint-major."""
    g = ctx.data.torque_map
    return (g[:, :, :, None] * per_joint[:, None, :, :]).reshape(ctx.n, 6, -1)


def _kinematic(ctx: Context) -> np.ndarray:
    """dW/dtheta without the spring-torque part: an angle change through the geometry alone."""
    d = ctx.data
    return d.angle_jacobian - d.torque_map * d.params.k


def _offset(ctx):
    return -ctx.data.angle_jacobian


def _rate(ctx):
    return _torque(ctx, (ctx.data.params.k * ctx.data.theta)[:, :, None])


def _count_angle(ctx) -> np.ndarray:
    """The angle the board's curves are evaluated at: the whole counts, rad."""
    return counts_from_angles(ctx.data.theta) * ENCODER_COUNT_RAD


def _spring_curve(ctx):
    # The diagnosis term's columns (its straight part removed: that stays with the rate),
    # at the count angle, with the nominal rate.
    return _torque(ctx, curves.spring_features(_count_angle(ctx), ctx.data.params.k))


def _encoder_curve(ctx):
    # The link's angle is the count angle minus e: as encoder_offset, per harmonic.
    feats = curves.encoder_features(_count_angle(ctx))                  # (n, 6, 2H)
    cols = -ctx.data.angle_jacobian[:, :, :, None] * feats[:, None, :, :]
    return cols.reshape(ctx.n, 6, -1)


def _geometry(ctx):
    d = ctx.data
    return np.concatenate([d.geometry_jacobian, _kinematic(ctx)[:, :, :3],
                           force_rotation(d, np.ones((ctx.n, 3)))], axis=-1)


def _hysteresis(ctx):
    return _torque(ctx, ctx.terms.hysteresis)


def _friction(ctx):
    t = ctx.terms
    speeds = ctx.cal.friction_speeds_rad_s
    v = friction_speed(t.speed, ctx.cal.friction_speed_limit_rad_s)
    feats = [np.clip(v / s, -1.0, 1.0) for s in speeds] + [v, t.direction]
    return _torque(ctx, np.stack(feats, axis=-1))


def _backlash(ctx):
    return ctx.data.angle_jacobian * (0.5 * ctx.terms.direction)[:, None, :]


def _compliance(ctx):
    d = ctx.data
    bending = _kinematic(ctx)[:, :, :3] * (d.params.k[:3] * d.theta[:, :3])[:, None, :]
    f0 = model.base_force(d.params, d.theta[:, :3])
    m_p = d.params.k[3:] * d.theta[:, 3:] + np.cross([0.0, 0.0, d.params.c], f0)
    tilt = force_rotation(d, m_p).sum(axis=-1, keepdims=True)
    return np.concatenate([bending, tilt], axis=-1)


def _add(cal: Calibration, **steps) -> Calibration:
    return cal.with_(**{k: np.asarray(getattr(cal, k)) + v for k, v in steps.items()})


def _apply_geometry(cal, c):
    return _add(cal, delta_a_mm=c[0:3], delta_b_mm=c[3:6], delta_la_mm=c[6:9],
                delta_lb_mm=c[9:12], delta_azimuth_rad=c[12:15],
                delta_rest_angle_rad=c[15:18], gimbal_misalignment_rad=c[18:21])


def _apply_friction(cal, c):
    c = c.reshape(6, -1)
    s = len(cal.friction_speeds_rad_s)
    return _add(cal, friction_sign_nm=c[:, :s], viscous_nm_s_per_rad=c[:, s],
                presliding_nm=c[:, s + 1])


def neutral_like(cal: Calibration) -> Calibration:
    """The neutral calibration with ``cal``'s design and settings (radii, speeds, filters)."""
    radii, speeds = cal.hysteresis_radii_counts, cal.friction_speeds_rad_s
    return Calibration(name=cal.name, design_name=cal.design_name, design_hash=cal.design_hash,
                       direction_half_counts=cal.direction_half_counts,
                       hysteresis_radii_counts=radii, hysteresis_nm=np.zeros((6, len(radii))),
                       speed_filter_s=cal.speed_filter_s, speed_lead_s=cal.speed_lead_s,
                       friction_speeds_rad_s=speeds,
                       friction_sign_nm=np.zeros((6, len(speeds))))


_TERMS = {t.name: t for t in TERMS}


def _nearest(values, grid) -> np.ndarray:
    """Index of the nearest grid point to each value on a log scale."""
    return np.argmin(np.abs(np.log(np.asarray(values, float))[:, None]
                            - np.log(np.asarray(grid, float))[None, :]), axis=1)


def _per_joint_map(blocks: np.ndarray) -> np.ndarray:
    """A map that acts joint by joint with the same (term per joint, family per joint) block."""
    return np.kron(np.eye(6), blocks)


def _hysteresis_map(radii) -> np.ndarray:
    block = np.zeros((len(HYSTERESIS_RADII), len(radii)))
    block[_nearest(np.asarray(radii) * ENCODER_COUNT_RAD, HYSTERESIS_RADII),
          np.arange(len(radii))] = 1.0
    return _per_joint_map(block)


def _friction_map(speeds) -> np.ndarray:
    v = len(FRICTION_VELOCITIES_RAD_S)
    block = np.zeros((v + 2, len(speeds) + 2))
    block[_nearest(speeds, FRICTION_VELOCITIES_RAD_S), np.arange(len(speeds))] = 1.0
    block[v, len(speeds)] = block[v + 1, len(speeds) + 1] = 1.0     # viscous, pre-sliding
    return _per_joint_map(block)


def _friction_constraints(cal):
    """Friction opposes the motion: per joint, the torque of the sign levels and the viscous
    term is >= 0 at every sign speed (it is piecewise linear in the speed, zero at rest, so
    that holds it at every speed up to the last; a Stribeck dip of one level below another
    stays allowed), and the viscous coefficient is >= 0 (the slope beyond). Pre-sliding is
    left free: its direction state also carries what the causal backlash switch misses."""
    speeds = np.asarray(cal.friction_speeds_rad_s, dtype=float)
    s = len(speeds)
    block = np.zeros((s + 1, s + 2))
    block[:s, :s] = np.minimum(speeds[:, None] / speeds[None, :], 1.0)
    block[:s, s] = speeds
    block[s, s] = 1.0
    a = _per_joint_map(block)
    return a, np.zeros(len(a))


def _backlash_constraints(cal):
    """The gimbal joints' plays within what the board's first-order turn of those joints holds
    to 0.01 % FS (``MAX_GIMBAL_PLAY_RAD``; codegen refuses more): a fit beyond it is held at
    the bound there, and the branches keep their own."""
    a = np.zeros((6, 6))
    for row, j in enumerate((3, 4, 5)):
        a[2 * row, j], a[2 * row + 1, j] = 1.0, -1.0
    return a, np.full(6, -MAX_GIMBAL_PLAY_RAD)


def _friction_values(cal):
    return np.concatenate([cal.friction_sign_nm, cal.viscous_nm_s_per_rad[:, None],
                           cal.presliding_nm[:, None]], axis=1).ravel()


def _compliance_map() -> np.ndarray:
    out = np.zeros((7, 4))        # term: axial (3), bending (3), tilt; family: elbow (3), tilt
    out[3:6, 0:3] = np.eye(3)
    out[6, 3] = 1.0
    return out


_GEOMETRY_FIELDS = ("delta_a_mm", "delta_b_mm", "delta_la_mm", "delta_lb_mm",
                    "delta_azimuth_rad", "delta_rest_angle_rad", "gimbal_misalignment_rad")

JOINTS = tuple(f"j{i}" for i in range(1, 7))
BRANCHES = tuple(f"b{i}" for i in range(1, 4))


def families(cal: Calibration, design=None) -> dict[str, Family]:
    """The families for a calibration's settings (radii and speeds fix their widths), with
    the diagnosis's sizes for ``design`` (None: as written, the shipped design's)."""
    plain = _families(cal)
    if design is None:
        return plain
    sized = {t.name: t for t in for_design(tuple(_TERMS[name] for name in plain), design)}
    return {name: dataclasses.replace(f, sized_term=sized[name])
            if sized[name] is not _TERMS[name] else f for name, f in plain.items()}


def _families(cal: Calibration) -> dict[str, Family]:
    radii = cal.hysteresis_radii_counts
    speeds = cal.friction_speeds_rad_s
    geometry_names = tuple(f"delta_{k}_{b}_mm" for k in ("a", "b", "la", "lb") for b in BRANCHES) \
        + tuple(f"delta_azimuth_{b}_rad" for b in BRANCHES) \
        + tuple(f"delta_rest_angle_{b}_rad" for b in BRANCHES) \
        + tuple(f"gimbal_misalignment_{a}_rad" for a in "xyz")
    return {f.effect: f for f in (
        Family("encoder_offset", tuple(f"offset_{j}_rad" for j in JOINTS), _offset,
               lambda c, x: _add(c, offset_rad=x), lambda c: np.asarray(c.offset_rad),
               np.eye(6), ("offset_rad",)),
        Family("stiffness_mismatch", tuple(f"rate_ratio_{j}" for j in JOINTS), _rate,
               lambda c, x: _add(c, rate_ratio=x), lambda c: np.asarray(c.rate_ratio) - 1.0,
               np.eye(6), ("rate_ratio",)),
        Family("geometry_error", geometry_names, _geometry, _apply_geometry,
               lambda c: np.concatenate([getattr(c, f) for f in _GEOMETRY_FIELDS]),
               np.eye(21), _GEOMETRY_FIELDS),
        Family("spring_hysteresis", tuple(f"hysteresis_{j}_r{r}_nm" for j in JOINTS for r in radii),
               _hysteresis, lambda c, x: _add(c, hysteresis_nm=x.reshape(6, -1)),
               lambda c: np.asarray(c.hysteresis_nm).ravel(), _hysteresis_map(radii),
               ("hysteresis_nm",)),
        Family("joint_friction", tuple(f"{k}_{j}" for j in JOINTS for k in
                                       tuple(f"sign_v{v:g}_nm" for v in speeds)
                                       + ("viscous_nm_s_per_rad", "presliding_nm")),
               _friction, _apply_friction, _friction_values, _friction_map(speeds),
               ("friction_sign_nm", "viscous_nm_s_per_rad", "presliding_nm"),
               constraints=_friction_constraints),
        Family("backlash", tuple(f"backlash_play_{j}_rad" for j in JOINTS), _backlash,
               lambda c, x: _add(c, backlash_play_rad=x),
               lambda c: np.asarray(c.backlash_play_rad),
               _per_joint_map(np.eye(len(_TERMS["backlash"].param_names) // 6, 1)),
               ("backlash_play_rad",), constraints=_backlash_constraints),
        # The two curves: their parameters are the diagnosis terms' coefficients themselves.
        Family("nonlinear_spring", tuple(f"{k}_{j}" for j in JOINTS
                                         for k in ("abs_quadratic", "cubic")),
               _spring_curve, lambda c, x: _add(c, spring_curvature=x.reshape(6, -1)),
               lambda c: np.asarray(c.spring_curvature).ravel(), np.eye(12),
               ("spring_curvature",)),
        # Over the joint range the harmonics are nearly collinear: the term judges the error
        # curve they make together (``_encoder_plausible``), not each harmonic alone.
        Family("encoder_periodic_error",
               tuple(f"{k}{h}_{j}_rad" for j in JOINTS for h in curves.ENCODER_HARMONICS
                     for k in ("sin", "cos")),
               _encoder_curve, lambda c, x: _add(c, encoder_periodic_rad=x.reshape(6, -1)),
               lambda c: np.asarray(c.encoder_periodic_rad).ravel(),
               np.eye(6 * 2 * len(curves.ENCODER_HARMONICS)), ("encoder_periodic_rad",),
               each_parameter=False),
        Family("link_compliance", tuple(f"elbow_{b}_rad_per_nm" for b in BRANCHES)
               + ("tilt_rad_per_nm",), _compliance,
               lambda c, x: _add(c, elbow_rad_per_nm=x[:3]).with_(
                   tilt_rad_per_nm=float(c.tilt_rad_per_nm + x[3])),
               lambda c: np.append(c.elbow_rad_per_nm, c.tilt_rad_per_nm), _compliance_map(),
               ("elbow_rad_per_nm", "tilt_rad_per_nm")),
    )}
