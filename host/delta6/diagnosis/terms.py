"""Candidate effects: each unmodelled effect of the twin's vocabulary as a parametric term added
to the analytical model, linear in its parameters around the nominal model.

A term is identified by its *signature*, not by the twin's equations: each family is built
from what the physics says the effect can depend on, flexibly enough to cover formulations the
twin does not use:

==================  ==========  =======================================================
effect              acts on     what the term can express
==================  ==========  =======================================================
encoder_offset      angle       a constant angle error per joint
stiffness_mismatch  torque      a spring-rate error per joint (torque proportional to angle)
geometry_error      geometry    errors of a, b, la, lb and azimuth of each branch
spring_hysteresis   torque      rate-independent history: Prandtl-Ishlinskii play operators
                                of several widths (the loop shape is free)
joint_friction      torque      Coulomb (smooth sign of velocity) plus viscous, per joint
backlash            angle       lost motion: the angle is off by +-play/2 depending on the
                                direction of the last motion (zero-width switching)
link_compliance     geometry    link deformation proportional to load: axial stretch of
                                each distal link, bending of each proximal link
sensor_latency      time        the reference lags: first and second time derivatives
thermal_drift       angle, k    offset and spring-rate changes proportional to temperature
nonlinear_spring    torque      a spring rate that changes with the deflection (odd
                                powers of the angle: stiffening or softening)
encoder_periodic_   angle       an encoder error periodic in the shaft angle (harmonics
error                           1..4 of a turn, any phase)
harness             torque      a parallel elastic path (a cable to the plate): a force on
                                the plate affine in the plate's pose, plus one-sided terms
                                (a slack cable that only pulls once taut), through the
                                mechanism to the joints (second pass: at the clamp, all
                                six joints, one cable of searched direction and slack)
==================  ==========  =======================================================

Every term returns *columns*: the wrench change (N, N*m) per unit of each parameter, per
sample, shape (n, 6, p), with the parameters in physical units.
"""
from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np

from delta6.core import curves
from delta6.core.model import ENCODER_COUNT_RAD, base_force, forward_kinematics, link_tension, rotation
from delta6.diagnosis.data import GapData
from delta6.diagnosis.sensitivity import GEOMETRY_NAMES
from delta6.diagnosis.signals import VELOCITY_MIN_CUBIC_HALF, moving_average, smooth_velocity

#: Widths (radius, rad) of the hysteresis play operators, doubling from 16 encoder counts
#: to a fifth of the joint range: enough to follow an exponential (Dahl, Bouc-Wen) approach
#: as well as a piecewise-linear (Preisach) loop. The smallest stays above the backlash
#: family's widths, so the two differ in what they express (a gradual loop vs a switch).
HYSTERESIS_RADII = (0.006, 0.012, 0.024, 0.048, 0.096)
#: Play (radius, rad) of the gradual pick-up feature of the backlash family (contacts that
#: take the load one after another): below the smallest hysteresis width, so the two
#: families stay apart.
BACKLASH_PICKUP_RAD = (0.004,)
#: Longest stretch of a still encoder taken as the dwell of a reversal, s.
BACKLASH_MAX_DWELL_S = 0.6
#: Time constants of the lagged temperatures in the thermal family, s: together with the
#: temperature itself they span thermal lags from none to several minutes.
THERMAL_LAGS_S = (40.0, 200.0)
#: Dead band of the backlash direction detector: ignores encoder flicker of +-1 count.
BACKLASH_SWITCH_RAD = 1.5 * ENCODER_COUNT_RAD
#: Velocity scales of the smooth Coulomb signs, rad/s: a sharp one near the velocity
#: resolution of smoothed 14-bit encoders, and a broad one for Stribeck-like curves.
FRICTION_VELOCITIES_RAD_S = (0.003, 0.01, 0.04)

JOINTS = tuple(f"j{i}" for i in range(1, 7))


@dataclass(frozen=True)
class Term:
    name: str
    acts_on: str
    param_names: tuple[str, ...]
    unit: str
    build: Callable[[GapData], np.ndarray]
    needs_temperature: bool = False
    #: Physical summary of fitted coefficients (comparable with the twin's truth summaries).
    summary: Callable[[np.ndarray], dict] | None = None
    #: Prior scale of each parameter (the size the effect plausibly has, physical units): the
    #: fits regularise towards zero with it (``selection``). None: no prior.
    prior_sd: tuple[float, ...] | None = None
    #: Plausibility: fitted coefficients -> [(quantity, values, limit)], the physical
    #: quantities a fit must keep within ``limit`` to be a believable instance of the effect.
    plausible: Callable[[np.ndarray], list] | None = None
    #: Samples where only this effect shows (view -> (n,) bool), tested on their own.
    signature: Callable[[GapData], np.ndarray] | None = None
    #: Effects told apart only by details share a group (a verdict names the group when the
    #: log cannot separate them).
    group: str | None = None
    #: The family this one refines (it contains its shape and more: a stiffening spring
    #: is a spring-rate error plus curvature); named first when both are named.
    refines: str | None = None
    #: Per own parameter of a joint, how much of the ``refines`` family's parameter of that
    #: joint the own column leaves out by construction (its straight-line part): adding it back
    #: gives the refinement's physical form (a stiffening spring with the nominal rate at
    #: rest), against which the refined family must show a part of its own to be named.
    straight_part: tuple[float, ...] | None = None
    #: Per quantity of ``plausible``, a factor on its limit per value (one factor for all
    #: values, or one per value): set by :func:`for_design` for a design whose springs or
    #: links make the shipped design's sizes too tight (empty: the limits as written).
    limit_scale: tuple[tuple[str, tuple[float, ...]], ...] = ()
    #: What physics keeps at or above zero: () -> [(quantity, maps, tolerance)], each map
    #: (6, k, width) taking the coefficients to k values per joint (a friction's torque against
    #: the motion at k speeds): see :meth:`sign_checks`.
    one_sided: Callable[[], list] | None = None

    def summarize(self, coef: np.ndarray) -> dict:
        out = {name: float(v) for name, v in zip(self.param_names, coef)}
        if self.summary is not None:
            out.update(self.summary(np.asarray(coef, dtype=float)))
        return out

    def plausibility(self, coef: np.ndarray, cov: np.ndarray | None = None) -> list[dict]:
        """Every physical quantity of a fit against its plausible limit. With the covariance
        ``cov`` of the coefficients, a parameter counts only by how far it is out of bounds
        beyond three standard errors (a combination the log cannot separate, two lengths
        that cancel, is undetermined, not implausible)."""
        coef = np.asarray(coef, dtype=float)
        shrunk = coef
        if cov is not None:
            se = np.sqrt(np.maximum(np.diag(cov), 0.0))
            shrunk = np.sign(coef) * np.maximum(np.abs(coef) - 3.0 * se, 0.0)
        return self._judge(self.plausible(shrunk) if self.plausible is not None else [])

    def sign_checks(self, coef: np.ndarray, cov: np.ndarray | None = None) -> list[dict]:
        """What physics keeps at or above zero (``one_sided``), as :meth:`plausibility`'s
        checks: per joint, how far its values go below zero beyond three of their standard
        errors (from the covariance ``cov``), against the tolerance. The diagnosis judges a
        fit's signs this way; the calibration imposes them in its fit instead."""
        coef = np.asarray(coef, dtype=float)
        checks = []
        for quantity, maps, tolerance in (self.one_sided() if self.one_sided else []):
            values = maps @ coef                                         # (6, k)
            sd = (np.sqrt(np.maximum(np.einsum("jkw,wv,jkv->jk", maps, cov, maps), 0.0))
                  if cov is not None else 0.0)
            checks.append((quantity, np.maximum(-values - 3.0 * sd, 0.0).max(axis=1),
                           tolerance))
        return self._judge(checks)

    def _judge(self, checks) -> list[dict]:
        """[(quantity, values, limit)] -> each quantity's worst value against its limit."""
        scales = dict(self.limit_scale)
        out = []
        for quantity, values, limit in checks:
            values = np.atleast_1d(np.asarray(values, dtype=float))
            if quantity in scales and values.size:
                # Each value against its own limit; the worst one is reported.
                limits = float(limit) * np.broadcast_to(np.asarray(scales[quantity]),
                                                        values.shape)
                at = int(np.argmax(np.abs(values) / limits))
                worst, limit = float(abs(values[at])), float(limits[at])
            else:
                worst = float(np.max(np.abs(values))) if values.size else 0.0
            out.append({"quantity": quantity, "largest": worst, "limit": float(limit),
                        "ratio": worst / limit if limit > 0 else float("inf")})
        return out

    def available(self, data: GapData) -> bool:
        return not self.needs_temperature or (data.temp_c is not None
                                              and np.ptp(data.temp_c) >= 0.5)

    def columns(self, data: GapData) -> np.ndarray:
        cols = self.build(data)
        assert cols.shape == (len(data), 6, len(self.param_names)), (self.name, cols.shape)
        return cols


def _torque_columns(data: GapData, per_joint: np.ndarray) -> np.ndarray:
    """Extra joint torques -> wrench: G[:, :, j] * per_joint[:, j, m] for every joint and
    feature m: (n, 6, 6*m), ordered joint-major."""
    g = data.torque_map                                          # (n, 6, 6)
    cols = g[:, :, :, None] * per_joint[:, None, :, :]           # (n, 6, 6, m)
    return cols.reshape(len(data), 6, -1)


def _encoder_offset(data: GapData) -> np.ndarray:
    # The encoder reads theta + delta: the true angle is theta_enc - delta.
    return -data.angle_jacobian


def _stiffness(data: GapData) -> np.ndarray:
    tau = data.params.k * data.theta
    return _torque_columns(data, tau[:, :, None])


def _kinematic_part(data: GapData) -> np.ndarray:
    """dW/dtheta_j minus its torque part G_j k_j: what an angle change does through the
    geometry alone (the spring torque unchanged), (n, 6, 6)."""
    return data.angle_jacobian - data.torque_map * data.params.k


def force_rotation(data: GapData, vectors: np.ndarray) -> np.ndarray:
    """Wrench change when {E0} turns by a small rotation about each {B} axis e_k, scaled by
    ``vectors`` (n, 3) per sample (or ones): Delta F_E = -R^T (e_k x F0), moments unchanged.
    Returns (n, 6, 3)."""
    f0 = base_force(data.params, data.theta[:, :3])
    rt = np.swapaxes(rotation(data.theta[:, 3:]), -1, -2)
    cols = np.zeros((len(data), 6, 3))
    for k in range(3):
        axis = np.zeros(3)
        axis[k] = 1.0
        turned = np.cross(axis, f0) * vectors[:, k:k + 1]
        cols[:, :3, k] = -np.einsum("nij,nj->ni", rt, turned)
    return cols


def _geometry(data: GapData) -> np.ndarray:
    # Lengths and azimuths per branch, the rest angle of each proximal link (a kinematic
    # angle shift that leaves the spring torque alone), and a misaligned gimbal unit.
    rest = _kinematic_part(data)[:, :, :3]
    tilt = force_rotation(data, np.ones((len(data), 3)))
    return np.concatenate([data.geometry_jacobian, rest, tilt], axis=-1)


def _hysteresis(data: GapData) -> np.ndarray:
    # Torque per N*m of loop half-height, for each play width.
    return _torque_columns(data, data.play_state(HYSTERESIS_RADII))


#: The velocity fits the friction family chooses among, per log: a line over two samples
#: either side, and cubics over these half-widths, s (those holding at least
#: ``signals.VELOCITY_MIN_CUBIC_HALF`` samples either side at the log's rate).
VELOCITY_CUBIC_HALF_S = (0.05, 0.1, 0.2)
#: Samples the choice is made on (the log's first), and its contiguous blocks (alternate
#: blocks fit and score, then the other way round).
VELOCITY_CHOICE_SAMPLES = 100_000
VELOCITY_CHOICE_BLOCKS = 10


def speed_features(vel: np.ndarray) -> np.ndarray:
    """The friction family's functions of the joint speed, on a new last axis: its smooth signs
    at each of ``FRICTION_VELOCITIES_RAD_S`` and the speed itself (viscous)."""
    return np.stack([np.tanh(vel / v) for v in FRICTION_VELOCITIES_RAD_S] + [vel], axis=-1)


def velocity_windows(step: float) -> list[tuple[int, int]]:
    """The candidate (half width in samples, degree) of the velocity's fit at this step."""
    out = [(2, 1)]
    for half_s in VELOCITY_CUBIC_HALF_S:
        half = int(round(half_s / step)) if step > 0 else 0
        if half >= VELOCITY_MIN_CUBIC_HALF and (half, 3) not in out:
            out.append((half, 3))
    return out


def friction_velocity_window(data: GapData) -> tuple[int, int]:
    """The velocity fit with which the friction family's speed features explain the
    residual's joint torques best on held-out blocks. A longer window averages the counts'
    quantization away but bends the speed of a fast motion: which wins depends on the log's
    motion (a rig's slow moves and dither, or a faster excitation), so the log decides. Per
    joint, least squares on the family's smooth signs and viscous term plus a constant,
    fitted on alternate contiguous blocks and scored on the others, both ways round."""
    candidates = velocity_windows(data.step)
    n = min(len(data), VELOCITY_CHOICE_SAMPLES)
    if len(candidates) == 1 or n < 4 * VELOCITY_CHOICE_BLOCKS:
        return candidates[0]
    rows = slice(0, n)
    tau = data.joint_torque_of(data.residual[rows], rows)
    scores = []
    block = np.arange(n) * VELOCITY_CHOICE_BLOCKS // n
    for half, degree in candidates:
        vel = smooth_velocity(data.theta[rows], data.t[rows], half, step=data.step,
                              degree=degree)
        sse = 0.0
        for j in range(6):
            feats = np.column_stack([speed_features(vel[:, j]), np.ones(n)])
            for parity in (0, 1):
                fit = block % 2 == parity
                coef, *_ = np.linalg.lstsq(feats[fit], tau[fit, j], rcond=None)
                sse += float(np.sum((tau[~fit, j] - feats[~fit] @ coef) ** 2))
        scores.append(sse)
    return candidates[int(np.argmin(scores))]


def _friction(data: GapData) -> np.ndarray:
    # Any odd function of the joint speed that saturates (Coulomb, Stribeck) or grows
    # (viscous), plus the pre-sliding memory that holds the last direction's friction at rest.
    memory = data.play_state([BACKLASH_SWITCH_RAD])[:, :, 0]
    feats = np.concatenate([speed_features(data.smooth_velocity), memory[..., None]], axis=-1)
    return _torque_columns(data, feats)


def _backlash(data: GapData) -> np.ndarray:
    # Moving up, the encoder trails the link by play/2: true angle = encoder + play/2 * dir.
    # The direction switches across the dwell (encoder still, link turning through the play);
    # two small plays on the encoder angle let the pick-up be gradual (compliant contacts).
    # During the dwell the link leaves its turning point from rest, so the travel through the
    # play grows about with the square of the time (a quadratic ramp).
    ramp = data.dwell_ramp(BACKLASH_SWITCH_RAD, BACKLASH_MAX_DWELL_S, 0.5 * ENCODER_COUNT_RAD,
                           power=2.0)
    pickup = data.play_state(BACKLASH_PICKUP_RAD)
    feats = np.concatenate([ramp[:, :, None], pickup], axis=-1)              # (n, 6, 2)
    cols = data.angle_jacobian[:, :, :, None] * (0.5 * feats)[:, None, :, :]
    return cols.reshape(len(data), 6, -1)


def _compliance(data: GapData) -> np.ndarray:
    # Axial: each distal link stretches by c * (its force); bending: each proximal link's tip
    # moves as if the joint turned by c * (its torque), without changing the spring torque.
    tension = link_tension(data.params, data.theta[:, :3])          # signed link force, N
    dlb = data.geometry_jacobian[:, :, 9:12] * 1e3                 # per m of lb_i
    axial = dlb * tension[:, None, :]                               # per (m/N)
    bending = _kinematic_part(data)[:, :, :3] * (data.params.k[:3]
                                                  * data.theta[:, :3])[:, None, :]
    # The platform tilts with the moment about its centre P: the gimbal's moment plus the
    # force at {E}, c below P. The tilt turns the force like a misaligned gimbal would.
    f0 = base_force(data.params, data.theta[:, :3])
    m_p = data.params.k[3:] * data.theta[:, 3:] + np.cross([0.0, 0.0, data.params.c], f0)
    tilt = force_rotation(data, m_p).sum(axis=-1, keepdims=True)  # isotropic, rad/(N*m)
    return np.concatenate([axial * 1e-6, bending, tilt], axis=-1)  # axial in um/N


def _first_order_latency(data: GapData) -> np.ndarray:
    return -np.gradient(data.model, data.t, axis=0)[:, :, None]


def _latency(data: GapData) -> np.ndarray:
    # Reference(t) = true(t - tau) ~ true - tau dW/dt + tau^2/2 d2W/dt2.
    first = _first_order_latency(data)                          # -dW/dt
    return np.concatenate([first, -0.5 * np.gradient(first, data.t, axis=0)], axis=-1)


def _backlash_summary(coef: np.ndarray) -> dict:
    # Total lost motion per joint: the sum of the switching parts, whatever their widths.
    return {"play_rad": coef.reshape(6, -1).sum(axis=1).tolist()}


def _hysteresis_summary(coef: np.ndarray) -> dict:
    # After a reversal larger than every play width the loop's branches are sum(w) apart on
    # either side: the half-width of the torque loop at the joint.
    w = coef.reshape(6, len(HYSTERESIS_RADII))
    return {"loop_half_width_nm": w.sum(axis=1).tolist()}


def friction_curve(coef: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Steady-state friction torque (N*m) of each joint at the given positive speeds,
    (6, len(speed)), from fitted coefficients (the memory term is +1 while sliding)."""
    c = np.asarray(coef, dtype=float).reshape(6, -1)
    return c @ _sliding_features(speed).T


def _sliding_features(speed) -> np.ndarray:
    """The friction family's features of each joint while sliding at ``speed`` (the memory
    term at +1), (len(speed), width)."""
    speed = np.asarray(speed, dtype=float)
    return np.concatenate([speed_features(speed), np.ones_like(speed)[..., None]], axis=-1)


#: Speeds at which a fitted friction must oppose the motion (rad/s), and by how much it may
#: push along it (N*m; the smallest real friction is about this size) before the fit counts
#: as something else, such as a late reference (whose error is a negative viscous term).
DISSIPATION_SPEEDS_RAD_S = np.geomspace(0.01, 0.5, 8)
DISSIPATION_TOLERANCE_NM = 1e-3


@functools.lru_cache(maxsize=1)
def _friction_dissipates():
    # Per joint, the steady-state curve at each speed is a fixed row on that joint's
    # coefficients (friction_curve's features). Built once: plausibility runs often.
    feats = _sliding_features(DISSIPATION_SPEEDS_RAD_S)
    width = feats.shape[1]
    maps = np.zeros((6, len(feats), 6 * width))
    for j in range(6):
        maps[j, :, j * width:(j + 1) * width] = feats
    maps.setflags(write=False)          # shared by every call (cached)
    return [("torque_along_motion_nm", maps, DISSIPATION_TOLERANCE_NM)]


def _friction_summary(coef: np.ndarray) -> dict:
    # Formulation-free figures, like the twin's truth: a line over 0.05..0.5 rad/s and the
    # torque at 0.1 rad/s.
    speeds = np.linspace(0.05, 0.5, 10)
    curve = friction_curve(coef, speeds)
    slope, intercept = np.polyfit(speeds, curve.T, 1)
    return {"coulomb_equiv_nm": intercept.tolist(), "viscous_equiv_nm_s_per_rad": slope.tolist(),
            "torque_at_ref_speed_nm": friction_curve(coef, [0.1])[:, 0].tolist()}


def _thermal_summary(coef: np.ndarray) -> dict:
    c = coef.reshape(1 + len(THERMAL_LAGS_S), 2, 6)     # lag, kind, joint
    total = c.sum(axis=0)                # the settled response per degC
    return {"stiffness_coeff_per_c": total[0].tolist(), "offset_coeff_rad_per_c": total[1].tolist()}


def _thermal(data: GapData) -> np.ndarray:
    # Relative to the temperature at which k and the encoder zeros were set (the design's
    # calibration temperature): a warm log is a soft spring even if its temperature is
    # constant. Lagged copies of the temperature cover parts that warm up slowly.
    temps = [data.temp_c - data.ref_temp_c]
    temps += [data.lagged_temp(lag) - data.ref_temp_c for lag in THERMAL_LAGS_S]
    parts = []
    for temp in temps:
        dt = temp[:, None, None]
        parts += [_stiffness(data) * dt, _encoder_offset(data) * dt]
    return np.concatenate(parts, axis=-1)


#: Reference deflection of the nonlinear-spring family, rad (about the joint limit): its
#: parameters are the extra torque there as a fraction of the nominal spring torque. The
#: calibration's curves (``delta6.core.curves``) hold the same shapes: one definition.
NONLINEAR_REF_RAD = curves.SPRING_REF_RAD
#: The straight-line part taken out of the stiffening spring's |u| and u^2 columns (their
#: least-squares slope for u uniform in [-1, 1]): E[u^2 |u|] / E[u^2], E[u^4] / E[u^2].
NONLINEAR_STRAIGHT_PART = curves.SPRING_STRAIGHT_PART
#: Friction, hysteresis and backlash: a joint torque that depends on the direction of motion.
DIRECTION_DEPENDENT = "direction-dependent joint torque"
#: A stiffening spring (torque side) and an encoder's periodic error (angle side) both show
#: as a joint torque error that is a smooth curve in the joint's own angle: over the joint
#: range four harmonics of a shaft turn and a spring's curvature can stand in for each other.
SMOOTH_IN_ANGLE = "joint torque smooth in the joint's angle"
#: Harmonics of a shaft turn in the encoder family (the calibration's curve has the same).
ENCODER_HARMONICS = curves.ENCODER_HARMONICS
#: Largest part of an encoder's periodic error beyond a straight line over the joint range
#: (+-NONLINEAR_REF_RAD), rad. Over that sixth of a turn harmonic h bends away from its line
#: by at most 0.08, 0.31, 0.62, 0.95 times its amplitude (h = 1..4); a magnet's error of
#: about a degree (0.017 rad) in the first harmonic, falling as 1/h above it, bends by 0.012
#: at most with every phase aligned. A bend beyond that is a curve in the joint's torque
#: (a stiffening spring of about 7 % or more bends by 0.17-0.35 times its stiffening), not
#: the encoder's.
ENCODER_BENT_LIMIT_RAD = 0.012
#: Finite-difference step of the plate position's Jacobian, rad.
_FK_STEP = 1e-6


def _nonlinear_spring(data: GapData) -> np.ndarray:
    # Odd in the angle (a spring pair is symmetric), beyond the linear rate: |u| and u^2 times
    # the nominal torque (u = theta / reference), each minus its linear part over the joint
    # range (u uniform in [-1, 1]: E[u^2 |u|] / E[u^2] = 3/4, E[u^4] / E[u^2] = 3/5), so that a
    # spring-rate error stays with stiffness_mismatch. The parameters are the curvature:
    # the extra torque at the reference beyond the straight line, as a fraction of nominal,
    # is 0.25 * p1 + 0.4 * p2.
    u = data.theta / NONLINEAR_REF_RAD
    tau = data.params.k * data.theta
    lin_abs, lin_sq = NONLINEAR_STRAIGHT_PART
    feats = np.stack([tau * (np.abs(u) - lin_abs), tau * (u**2 - lin_sq)], axis=-1)
    return _torque_columns(data, feats)


def _encoder_periodic(data: GapData) -> np.ndarray:
    # Angle error e(q) = sum_h a_h sin(h q) + b_h (cos(h q) - 1): any phase of each harmonic,
    # zero at the rest angle where the encoders were zeroed.
    parts = []
    for h in ENCODER_HARMONICS:
        parts += [np.sin(h * data.theta), np.cos(h * data.theta) - 1.0]
    feats = np.stack(parts, axis=-1)                                   # (n, 6, 2H)
    cols = -data.angle_jacobian[:, :, :, None] * feats[:, None, :, :]  # (n, 6, 6, 2H)
    return cols.reshape(len(data), 6, -1)


def plate_jacobian(data: GapData) -> np.ndarray:
    """d(plate centre)/d(theta_1..3), m/rad, (n, 3, 3) (forward differences)."""
    here = forward_kinematics(data.params, data.theta[:, :3])
    out = np.empty((len(data), 3, 3))
    for j in range(3):
        step = np.zeros(3)
        step[j] = _FK_STEP
        out[:, :, j] = (forward_kinematics(data.params, data.theta[:, :3] + step) - here) \
            / _FK_STEP
    return out


#: Directions (in {B}) a slack cable may pull along: the 13 axes of a cube (faces, edges,
#: corners), so that any direction is within 28 degrees of one and a blend of neighbours
#: follows the rest.
HARNESS_DIRECTIONS = tuple(
    tuple(float(c) / float(np.linalg.norm(d)) for c in d) for d in
    ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1),
     (0, 1, -1), (1, 1, 1), (1, 1, -1), (1, -1, 1), (-1, 1, 1)))
#: The displacement (mm) the one-sided terms are stated at: a force c * x|x| / ref is c N per
#: mm there, like a stiffness.
HARNESS_REF_MM = 10.0
#: The one-sided terms per direction: |x| (with the affine part, a hinge at rest: a cable
#: that pulls one way only), x|x| and x^2 (with |x|, a hinge whose pull grows with the
#: stretch, and any slack up to the reference displacement, approximately).
_ONE_SIDED = ("abs", "abs_signed", "square")


def clamp_displacement(data: GapData, clamp_mm) -> tuple[np.ndarray, np.ndarray]:
    """A clamp ``clamp_mm`` (plate frame {E}, mm) off the plate's centre: its displacement
    from rest (n, 3, mm, {B}) and its motion per joint angle (n, 3, 6, m/rad)."""
    c = np.asarray(clamp_mm, float) * 1e-3
    rest = forward_kinematics(data.params, np.zeros((1, 3)))[0]
    q = data.theta[:, 3:]
    turned = rotation(q) @ c                                           # (n, 3) m
    disp = (data.position_mm - rest * 1e3) + (turned - c) * 1e3
    jac = np.empty((len(data), 3, 6))
    jac[:, :, :3] = plate_jacobian(data)
    for i in range(3):
        step = np.zeros(3)
        step[i] = _FK_STEP
        jac[:, :, 3 + i] = (rotation(q + step) @ c - turned) / _FK_STEP
    return disp, jac


def _plate_force(data: GapData, clamp_mm=None) -> tuple[np.ndarray, np.ndarray]:
    """Where a force acts on the plate and what it does: the point's displacement from rest
    (n, 3, mm, {B}) and the wrench change per N of force along x, y, z of {B} (n, 6, 3). At
    the plate's centre (``clamp_mm`` None) the force reaches joints 1..3 as J_p^T f (virtual
    work) and the wrench as G J_p^T f; at a clamp off the centre (plate frame, mm) it also
    turns the gimbal: J_c^T f on all six joints, J_c the clamp's motion per joint angle."""
    if clamp_mm is None:
        rest = forward_kinematics(data.params, np.zeros((1, 3)))[0]
        disp = data.position_mm - rest * 1e3
        force = np.einsum("naj,nkj->nak", data.torque_map[:, :, :3], plate_jacobian(data))
    else:
        disp, jac_c = clamp_displacement(data, clamp_mm)
        force = np.einsum("naj,nkj->nak", data.torque_map, jac_c)
    return disp, force


def cable_stretch_features(x: np.ndarray, slack_mm: float) -> np.ndarray:
    """The one-sided features of a slack cable stretched by ``x`` (mm, (n,)) along its own
    direction: the stretch beyond the slack, and its square over ``HARNESS_REF_MM`` (a pull
    that grows with the stretch, linearly or ever harder), both zero while the cable is slack.
    (n, 2)."""
    r = np.maximum(np.asarray(x, float) - slack_mm, 0.0)
    return np.stack([r, r * r / HARNESS_REF_MM], axis=-1)


def _harness(data: GapData, clamp_mm=None, cable=None) -> np.ndarray:
    # A cable or harness pulls on the plate with a force that depends on where the plate is:
    # affine in its pose's displacement from rest, the plate centre's (dp, mm) and the
    # gimbal's angles (q4..6, rad: a clamp off the centre moves with the tilt). The force f
    # reaches joints 1..3 as J^T f (virtual work) and the wrench as G J^T f. (The moment such
    # a clamp puts on the gimbal is left out while the clamp is unknown: on joints 4..6 it
    # looks like their own spring rates and zeros, and in mixes it took those effects'
    # shares.)
    # A slack cable only pulls once taut, and ever harder as it stretches: along each
    # direction d of a fixed set, a force along d that is one-sided in x = d . dp.
    # With the clamp's offset known (``harness_clamp``), the displacement is the clamp's own
    # (the plate centre's plus the tilt's share), and the force, affine part included, turns
    # the gimbal too. With a cable's direction and slack found (``cable_search``), the
    # one-sided part is that one cable: a pull (any direction) growing with its stretch
    # beyond the slack, and zero while it is slack, whatever the pose.
    disp, force = _plate_force(data, clamp_mm)
    pose = np.concatenate([disp, data.theta[:, 3:]], axis=1)
    cols = [force]                                                     # preload, N
    for m in range(6):                                                 # per mm or rad
        cols.append(force * pose[:, None, m:m + 1])
    if cable is not None:
        direction, slack = cable
        feats = cable_stretch_features(disp @ np.asarray(direction, float), slack)
        for i in range(feats.shape[1]):
            cols.append(force * feats[:, None, i:i + 1])
        return np.concatenate(cols, axis=-1)
    dirs = np.asarray(HARNESS_DIRECTIONS)                              # (D, 3)
    along = force @ dirs.T                                             # (n, 6, D) per N
    x = disp @ dirs.T                                                  # (n, D) mm
    ax = np.abs(x)
    for feat in (ax, x * ax / HARNESS_REF_MM, x * x / HARNESS_REF_MM):
        cols.append(along * feat[:, None, :])
    return np.concatenate(cols, axis=-1)


#: Directions of the clamp's offset whose singular value is below this share of the largest
#: are left at zero: a cable's stiffness is nearly of rank one (a harness stiff along one
#: direction, a third of that across it, keeps all three).
HARNESS_CLAMP_RCOND = 0.1


def harness_clamp(affine: np.ndarray) -> np.ndarray:
    """The clamp's offset from the plate's centre (plate frame {E}, mm) that the harness
    family's affine fit ``affine`` (its first ``HARNESS_AFFINE`` coefficients) implies. The
    force follows the clamp's displacement, the plate centre's plus the tilt's share R(q) c -
    c: so its change per gimbal angle is its change per mm of the centre's displacement
    times the clamp's motion per angle, d(R c)/dq at rest, linear in c. A least-squares
    solve, minimum norm over the directions the fit determines (``HARNESS_CLAMP_RCOND``): a
    cable pulling along one direction only shows c's part across it, which is the only part
    that moves its hinge or turns the gimbal; the part along it stays zero rather than
    following the noise."""
    f = np.asarray(affine, float)[:HARNESS_AFFINE].reshape(7, 3)
    stiff = f[1:4].T                        # (force component, centre's x y z): N/mm
    tilt = f[4:7].T                         # (force component, gimbal angle): N/rad
    rows = []
    for k in range(3):                      # d(R e_k)/dq at rest, (3, 3): mm/rad per mm
        e = np.zeros(3)
        e[k] = 1.0
        motion = np.stack([(rotation(np.eye(3)[i] * _FK_STEP) @ e - e) / _FK_STEP
                           for i in range(3)], axis=1)
        rows.append((stiff @ motion).ravel())
    system = np.stack(rows, axis=1)          # (9, 3)
    return np.linalg.lstsq(system, tilt.ravel(), rcond=HARNESS_CLAMP_RCOND)[0]


#: A clamp estimated closer to the plate's centre than this (mm) is taken to be at it; one
#: further out than the plausibility limit is not believed (the first pass stays).
HARNESS_CLAMP_MIN_MM = 1.0
HARNESS_CLAMP_MAX_MM = 100.0


def harness_with_clamp(term: Term, clamp_mm, cable=None) -> Term:
    """The harness family with its displacement at a clamp ``clamp_mm`` off the centre (None:
    the centre) and, with ``cable`` (direction in {B}, slack in mm: ``cable_search``), its
    one-sided part that one cable's."""
    clamp = None if clamp_mm is None else tuple(float(v) for v in clamp_mm)
    if cable is None:
        return dataclasses.replace(term, build=functools.partial(_harness, clamp_mm=clamp))
    cable = (tuple(float(v) for v in cable[0]), float(cable[1]))
    return dataclasses.replace(
        term, build=functools.partial(_harness, clamp_mm=clamp, cable=cable),
        param_names=term.param_names[:HARNESS_AFFINE] + HARNESS_CABLE_PARAMS,
        prior_sd=term.prior_sd[:HARNESS_AFFINE] + (0.05,) * len(HARNESS_CABLE_PARAMS),
        plausible=_harness_cable_plausible)


def sphere_directions(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere (a Fibonacci lattice), (n, 3)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


#: Directions a slack cable's stretch is sought along: neighbours about 9 degrees apart, so
#: that one is within 7 degrees of the cable's (a hinge 7 degrees off stretches within
#: 0.75 % of the cable's own along the cable, and its pull is fitted in any direction).
HARNESS_CABLE_DIRECTIONS = sphere_directions(500)
#: Slacks sought (mm): from taut at rest to about half the plate's travel in a push (the
#: stretch's square follows a slack between two of them).
HARNESS_CABLE_SLACKS_MM = (0.0, 1.0, 2.0, 3.0, 4.5, 6.5, 9.0)
#: The search reads at most this many samples of a log (evenly spread): the cable's
#: direction and slack are two angles and a length, not a fit that needs every sample.
HARNESS_CABLE_SEARCH_SAMPLES = 4_000


def search_rows(n: int) -> slice:
    """The samples (of a log of ``n``) the cable's search reads: at most
    ``HARNESS_CABLE_SEARCH_SAMPLES``, evenly spread."""
    return slice(None, None, max(1, -(-n // HARNESS_CABLE_SEARCH_SAMPLES)))


def _search_view(data: GapData) -> GapData:
    rows = search_rows(len(data))
    return GapData(design=data.design, params=data.params, t=data.t[rows],
                   theta=data.theta[rows], reference=data.reference[rows],
                   temp_c=None, fs=data.fs, ref_temp_c=data.ref_temp_c, step=data.step)


def cable_search(data: GapData, clamp_mm=None, directions=None, target=None
                 ) -> tuple[np.ndarray, float, float]:
    """The slack cable that best explains the residual alone: its stretch direction ({B})
    and slack (mm) among ``HARNESS_CABLE_DIRECTIONS`` (or ``directions``) x
    ``HARNESS_CABLE_SLACKS_MM``, and the share of the residual's squared error it removes
    (in-sample, FS-normalised). The pull of each candidate is fitted freely (three components
    per feature); its stretch is the clamp's displacement along the direction (``clamp_mm``
    as in :func:`_plate_force`). ``target``: what the cable is to explain at the search's
    samples (``search_rows``; FS-normalised, (n, 6)), default the residual; in a mix, the
    harness's part of it (:func:`delta6.diagnosis.run.harness_target`)."""
    view = _search_view(data)
    disp, force = _plate_force(view, clamp_mm)
    y = view.residual / view.fs if target is None else target
    return _best_cable(disp, force, y, view.fs, directions)


def _best_cable(disp, force, y, fs, directions=None) -> tuple[np.ndarray, float, float]:
    """:func:`cable_search` on the clamp's displacement ``disp`` (n, 3, mm), the wrench per N
    of force there ``force`` (n, 6, 3), the residual ``y`` (n, 6) and the full scale ``fs``
    it is normalised by."""
    fs_force = force / fs[None, :, None]
    m = np.einsum("nak,nal->nkl", fs_force, fs_force).reshape(len(y), 9)
    v = np.einsum("nak,na->nk", fs_force, y)
    total = float((y * y).sum())
    best = (-np.inf, 0, 0.0)
    dirs = HARNESS_CABLE_DIRECTIONS if directions is None else np.asarray(directions, float)
    pairs = ((0, 0), (0, 1), (1, 1))
    for slack in HARNESS_CABLE_SLACKS_MM:
        for lo in range(0, len(dirs), 100):
            x = disp @ dirs[lo:lo + 100].T                              # (n, D) mm
            g = cable_stretch_features(x.T, slack)                      # (D, n, 2)
            gg = np.stack([g[..., f] * g[..., h] for f, h in pairs], axis=1)   # (D, 3, n)
            gm = (gg @ m).reshape(len(x.T), 3, 3, 3)                    # (D, pair, k, l)
            b = (np.swapaxes(g, 1, 2) @ v).reshape(len(x.T), 6)         # (D, f*3 + k)
            gram = np.empty((len(x.T), 6, 6))
            for p, (f, h) in enumerate(pairs):
                gram[:, 3 * f:3 * f + 3, 3 * h:3 * h + 3] = gm[:, p]
                gram[:, 3 * h:3 * h + 3, 3 * f:3 * f + 3] = np.swapaxes(gm[:, p], 1, 2)
            scale = np.sqrt(np.maximum(np.einsum("dii->di", gram), 1e-300))
            gram = gram / (scale[:, :, None] * scale[:, None, :])
            gram += 1e-9 * np.eye(6)
            coef = np.linalg.solve(gram, (b / scale)[..., None])[..., 0]
            gains = np.einsum("di,di->d", coef, b / scale)
            k = int(np.argmax(gains))
            if gains[k] > best[0]:
                best = (float(gains[k]), lo + k, slack)
    gain, index, slack = best
    return dirs[index].copy(), float(slack), gain / total if total > 0 else 0.0


#: Clamp offsets tried for a cable when the first pass gives none (mm, across the cable:
#: the part along it neither moves the hinge nor turns the gimbal), and the directions kept
#: near the cable's (degrees).
HARNESS_CABLE_CLAMP_RADII_MM = (8.0, 16.0, 25.0, 35.0, 50.0)
HARNESS_CABLE_CLAMP_ANGLES = 8
HARNESS_CABLE_NEAR_DEG = 20.0


def cable_clamp_search(data: GapData, direction, target=None
                       ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The clamp offset (plate frame, mm; at rest it is {B}'s) across a cable's stretch
    ``direction`` that, with the direction and slack searched again near it, explains most of
    the residual: (clamp, direction, slack, share removed). A cable clamped off the centre
    stretches with the tilt too; when the first pass's family cannot be fitted (a log that
    pushes one axis at a time), its affine fit does not give the clamp. ``target``: as in
    :func:`cable_search`."""
    u = np.asarray(direction, float) / np.linalg.norm(direction)
    e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    near = HARNESS_CABLE_DIRECTIONS[HARNESS_CABLE_DIRECTIONS @ u
                                    >= np.cos(np.radians(HARNESS_CABLE_NEAR_DEG))]
    view = _search_view(data)
    y = view.residual / view.fs if target is None else target
    # What does not depend on the clamp, once: the centre's displacement and Jacobian, the
    # gimbal's rotation and its change per angle (as in ``clamp_displacement``).
    centre, at_centre = _plate_force(view, None)
    jac_p = plate_jacobian(view)
    q = view.theta[:, 3:]
    turn = rotation(q)
    turns = [rotation(q + np.eye(3)[i] * _FK_STEP) for i in range(3)]
    best = (np.zeros(3),) + _best_cable(centre, at_centre, y, view.fs, near)
    angles = np.arange(HARNESS_CABLE_CLAMP_ANGLES) * 2 * np.pi / HARNESS_CABLE_CLAMP_ANGLES
    for radius in HARNESS_CABLE_CLAMP_RADII_MM:
        for angle in angles:
            clamp = radius * (np.cos(angle) * e1 + np.sin(angle) * e2)
            c = clamp * 1e-3
            turned = turn @ c
            jac = np.empty((len(view), 3, 6))
            jac[:, :, :3] = jac_p
            for i in range(3):
                jac[:, :, 3 + i] = (turns[i] @ c - turned) / _FK_STEP
            force = np.einsum("naj,nkj->nak", view.torque_map, jac)
            found = _best_cable(centre + (turned - c) * 1e3, force, y, view.fs, near)
            if found[2] > best[3]:
                best = (clamp,) + found
    return best


def _dwell_samples(data: GapData) -> np.ndarray:
    # Backlash's own signature: some encoder stands still across a reversal while its link
    # turns through the play (and the reference wrench moves). Hysteresis and friction
    # features of an encoder that does not move stay put there. The stretches a reversal was
    # spread over count, and so does an encoder inside its switch's dead band (inside the
    # play, if there is one) within 0.6 s of a time it moved the switch. An encoder that never
    # moves it (a joint a one-axis push hardly turns, or one held still on a count's edge,
    # flickering by a count) is no dwell: under long holds it had put the whole log in the
    # signature. (The approach and the pick-up around a dwell are no part of it: there a
    # LuGre friction's pre-sliding looks like a play.)
    ramp = data.dwell_ramp(BACKLASH_SWITCH_RAD, BACKLASH_MAX_DWELL_S, 0.5 * ENCODER_COUNT_RAD,
                           power=2.0)
    state = data.play_state((BACKLASH_SWITCH_RAD,))[:, :, 0]
    switch = data.theta - BACKLASH_SWITCH_RAD * state          # the play's output
    moved = np.zeros(state.shape, dtype=bool)
    moved[1:] = np.abs(np.diff(switch, axis=0)) > 1e-3 * ENCODER_COUNT_RAD
    inside = np.abs(ramp) < 1.0 - 1e-6          # up to rounding (a state is a difference)
    # Moved within 0.6 s either side: a window's share of moves above zero.
    near = moving_average(moved.astype(float), int(round(BACKLASH_MAX_DWELL_S / data.step))) > 0
    return ((ramp != state) | (inside & near)).any(axis=1)


def _each(limit_by_param) -> Callable[[np.ndarray], list]:
    """Plausibility of every parameter on its own: [(name, limit)] per parameter slice."""
    def check(coef):
        return [(name, coef[sl], limit) for name, sl, limit in limit_by_param]
    return check


def _per_joint(value: float, width: int = 1) -> tuple[float, ...]:
    return (value,) * (6 * width)


#: Plausible sizes (prior scales) and limits, physical units. Assembly of printed parts: a few
#: tenths of a millimetre and milliradians, at most 2 mm and 0.05 rad; spring rates within
#: +-40 % of nominal; torques from rubbing parts of a few mN*m, at most 50 mN*m (15 % of a
#: joint's torque span); play at most 0.05 rad (3 degrees); latency at most 0.2 s.
_MM, _MM_LIMIT, _RAD, _RAD_LIMIT = 0.5, 2.0, 0.01, 0.05
#: A reference later than this (ten samples of a 50 Hz rig) is not paired with the encoders
#: at all, and W - L dW/dt no longer describes it, s.
LATENCY_LIMIT_S = 0.2
_TORQUE, _TORQUE_LIMIT = 0.01, 0.05


def _hysteresis_plausible(coef):
    return [("loop_half_width_nm", coef.reshape(6, -1).sum(axis=1), _TORQUE_LIMIT)]


def _friction_plausible(coef):
    s = _friction_summary(coef)
    return [("coulomb_equiv_nm", s["coulomb_equiv_nm"], _TORQUE_LIMIT),
            ("viscous_equiv_nm_s_per_rad", s["viscous_equiv_nm_s_per_rad"], 0.05)]


def _backlash_plausible(coef):
    return [("play_rad", coef.reshape(6, -1).sum(axis=1), _RAD_LIMIT)]


def _encoder_plausible(coef):
    # The error curve over the joint range, not its harmonics one by one: over a sixth of a
    # turn the harmonics are nearly collinear, and large coefficients of opposite signs can
    # make a small error.
    q = np.linspace(-NONLINEAR_REF_RAD, NONLINEAR_REF_RAD, 101)
    basis = np.stack([f for h in ENCODER_HARMONICS
                      for f in (np.sin(h * q), np.cos(h * q) - 1.0)], axis=1)   # (101, 2H)
    curves = basis @ coef.reshape(6, -1).T                                        # (101, 6)
    line = np.stack([np.ones_like(q), q], axis=1)
    bent = curves - line @ np.linalg.lstsq(line, curves, rcond=None)[0]
    return [("angle_error_rad", np.abs(curves).max(axis=0), 0.03),
            ("angle_error_beyond_line_rad", np.abs(bent).max(axis=0), ENCODER_BENT_LIMIT_RAD)]


#: The harness family's parameters, in ``_harness``'s column order (the pose, then the
#: component): the force on the plate (x, y, z in {B}; N) at rest and per unit of the pose's
#: displacement (plate centre x, y, z in mm; gimbal angles 4..6 in rad).
_POSE_UNITS = ("_n", "_per_x_mm", "_per_y_mm", "_per_z_mm", "_per_q4_rad", "_per_q5_rad",
               "_per_q6_rad")
#: Prior scales: a cable's preload of a few tenths of a newton, a stiffness of a few
#: hundredths of a N/mm (0.5 N over 10 mm), a clamp up to about 20 mm off the centre (the
#: tilt terms are the stiffness times that offset).
#: The one-sided terms: a few hundredths of a N/mm too.
HARNESS_PRIORS = ((0.3,) * 3 + (0.05,) * 9 + (0.05 * 20.0,) * 9
                  + (0.05,) * (len(_ONE_SIDED) * len(HARNESS_DIRECTIONS)))
HARNESS_AFFINE = 7 * 3


def _harness_plausible(coef):
    # Limits: 3 N of preload, 0.5 N/mm, a clamp at most 100 mm off the centre; the one-sided
    # pull at most 0.5 N/mm along any direction, at the reference displacement.
    f = coef[:HARNESS_AFFINE].reshape(7, 3)        # pose, component
    one_sided = np.abs(coef[HARNESS_AFFINE:].reshape(len(_ONE_SIDED), -1)).sum(axis=0)
    return [("preload_n", f[0], 3.0), ("stiffness_n_per_mm", f[1:4], 0.5),
            ("stiffness_n_per_rad", f[4:], 0.5 * 100.0),
            ("one_sided_n_per_mm", one_sided, 0.5)]


#: The single cable's parameters (``harness_with_clamp`` with a cable): its pull (x, y, z in
#: {B}) per mm of stretch beyond the slack, and per mm of stretch times the stretch over the
#: reference displacement.
HARNESS_CABLE_PARAMS = tuple(f"cable_{kind}_{a}_n_per_mm" for kind in ("stretch", "stretch_sq")
                             for a in "xyz")


def _harness_cable_plausible(coef):
    # The affine part as the family's; the cable's pull at most 0.5 N/mm at the reference
    # stretch.
    checks = _harness_plausible(np.concatenate([coef[:HARNESS_AFFINE],
                                                np.zeros(len(_ONE_SIDED)
                                                         * len(HARNESS_DIRECTIONS))]))
    pull = np.abs(coef[HARNESS_AFFINE:].reshape(2, 3)).sum(axis=0)
    return checks[:-1] + [("one_sided_n_per_mm", pull, 0.5)]


def _thermal_plausible(coef):
    s = _thermal_summary(coef)
    return [("stiffness_coeff_per_c", s["stiffness_coeff_per_c"], 0.01),
            ("offset_coeff_rad_per_c", s["offset_coeff_rad_per_c"], 3e-3)]


TERMS: tuple[Term, ...] = (
    Term("encoder_offset", "angle", tuple(f"offset_{j}_rad" for j in JOINTS), "rad",
         _encoder_offset, prior_sd=_per_joint(_RAD),
         plausible=_each([("offset_rad", slice(0, 6), _RAD_LIMIT)])),
    Term("stiffness_mismatch", "torque", tuple(f"k_ratio_error_{j}" for j in JOINTS), "1",
         _stiffness, prior_sd=_per_joint(0.1),
         plausible=_each([("k_ratio_error", slice(0, 6), 0.4)])),
    Term("geometry_error", "geometry",
         GEOMETRY_NAMES + tuple(f"rest_angle_b{i}_rad" for i in (1, 2, 3))
         + tuple(f"gimbal_misalignment_{a}_rad" for a in "xyz"), "mm or rad", _geometry,
         prior_sd=(_MM,) * 12 + (_RAD,) * 9,
         plausible=_each([("length_error_mm", slice(0, 12), _MM_LIMIT),
                          ("angle_error_rad", slice(12, 21), _RAD_LIMIT)])),
    Term("spring_hysteresis", "torque",
         tuple(f"play_{j}_r{r:g}_nm" for j in JOINTS for r in HYSTERESIS_RADII), "N*m",
         _hysteresis, summary=_hysteresis_summary,
         prior_sd=_per_joint(_TORQUE, len(HYSTERESIS_RADII)), plausible=_hysteresis_plausible,
         group=DIRECTION_DEPENDENT),
    Term("joint_friction", "torque",
         tuple(f"{kind}_{j}" for j in JOINTS for kind in
               tuple(f"coulomb_v{v:g}_nm" for v in FRICTION_VELOCITIES_RAD_S)
               + ("viscous_nms_per_rad", "presliding_nm")),
         "N*m, N*m*s/rad", _friction, summary=_friction_summary,
         prior_sd=_per_joint(_TORQUE, len(FRICTION_VELOCITIES_RAD_S) + 2),
         plausible=_friction_plausible, one_sided=_friction_dissipates,
         group=DIRECTION_DEPENDENT),
    Term("backlash", "angle",
         tuple(f"{kind}_{j}_rad" for j in JOINTS
               for kind in ("play_dwell", *(f"pickup_r{r:g}_play" for r in BACKLASH_PICKUP_RAD))),
         "rad", _backlash, summary=_backlash_summary,
         prior_sd=_per_joint(_RAD, 1 + len(BACKLASH_PICKUP_RAD)), plausible=_backlash_plausible,
         signature=_dwell_samples, group=DIRECTION_DEPENDENT),
    Term("link_compliance", "geometry",
         tuple(f"axial_b{i}_um_per_n" for i in (1, 2, 3))
         + tuple(f"bending_j{i}_rad_per_nm" for i in (1, 2, 3)) + ("tilt_rad_per_nm",),
         "um/N, rad/(N*m)", _compliance, prior_sd=(20.0,) * 3 + (0.1,) * 4,
         plausible=_each([("axial_um_per_n", slice(0, 3), 100.0),
                          ("bending_rad_per_nm", slice(3, 6), 0.5),
                          ("tilt_rad_per_nm", slice(6, 7), 0.5)])),
    Term("sensor_latency", "time", ("latency_s", "latency_sq_s2"), "s, s^2", _latency,
         prior_sd=(0.05, 0.0025),
         plausible=_each([("latency_s", slice(0, 1), LATENCY_LIMIT_S),
                          ("latency_sq_s2", slice(1, 2), 0.04)])),
    Term("thermal_drift", "angle, k",
         tuple(f"{kind}_{lag}_{j}" for lag in ("now", *(f"lag{s:g}s" for s in THERMAL_LAGS_S))
               for kind in ("k_ratio_per_degc", "offset_rad_per_degc") for j in JOINTS),
         "1/degC, rad/degC", _thermal, needs_temperature=True, summary=_thermal_summary,
         prior_sd=(0.002,) * 6 + (3e-4,) * 6 + (0.002,) * 6 + (3e-4,) * 6 + (0.002,) * 6
         + (3e-4,) * 6, plausible=_thermal_plausible),
    Term("nonlinear_spring", "torque",
         tuple(f"{kind}_{j}" for j in JOINTS for kind in ("abs_quadratic", "cubic")), "1",
         _nonlinear_spring, prior_sd=_per_joint(0.05, 2),
         plausible=_each([("rate_change_at_ref", slice(0, 12), 0.6)]),
         refines="stiffness_mismatch", straight_part=NONLINEAR_STRAIGHT_PART,
         group=SMOOTH_IN_ANGLE),
    Term("encoder_periodic_error", "angle",
         tuple(f"{kind}{h}_{j}_rad" for j in JOINTS for h in ENCODER_HARMONICS
               for kind in ("sin", "cos")), "rad", _encoder_periodic,
         prior_sd=_per_joint(3e-3, 2 * len(ENCODER_HARMONICS)),
         plausible=_encoder_plausible, group=SMOOTH_IN_ANGLE),
    Term("harness", "torque",
         tuple(f"force_{a}{unit}" for unit in _POSE_UNITS for a in "xyz")
         + tuple(f"one_sided_{kind}_d{i}_n_per_mm" for kind in _ONE_SIDED
                 for i in range(len(HARNESS_DIRECTIONS))),
         "N, N/mm, N/rad", _harness, prior_sd=HARNESS_PRIORS, plausible=_harness_plausible),
)
EFFECT_NAMES = tuple(t.name for t in TERMS)
#: The families of a curve in each joint's own angle (a stiffening spring, an encoder's
#: periodic error): what the calibration tabulates per joint and the benchmark scores by
#: the joints they bend.
SMOOTH_IN_ANGLE_FAMILIES = tuple(t.name for t in TERMS if t.group == SMOOTH_IN_ANGLE)


# --- sizes for the design at hand -----------------------------------------------------------

#: The families whose sizes are torques at the joints (their parameters joint-major, every one
#: in N*m or N*m per speed), and the quantities of their plausibility checks that are.
TORQUE_FAMILIES = {"spring_hysteresis": ("loop_half_width_nm",),
                   "joint_friction": ("coulomb_equiv_nm", "viscous_equiv_nm_s_per_rad",
                                      "torque_along_motion_nm")}
#: The link compliance's parameters and quantities in rad per N*m (a bend at the elbow and
#: the plate's tilt), which grow as the links get shorter.
COMPLIANCE_PARAMS = slice(3, 7)
COMPLIANCE_QUANTITIES = ("bending_rad_per_nm", "tilt_rad_per_nm")


@functools.lru_cache(maxsize=1)
def _reference():
    """The shipped design the sizes above were chosen for."""
    from delta6.core.design import load
    from delta6.core.paths import DEFAULT_DESIGN
    return load(DEFAULT_DESIGN)


def design_scales(design) -> tuple[np.ndarray, float]:
    """Per joint, how much larger the design's spring torque over its joint box is than the
    shipped design's, and how much more a link of its length bends per N*m (the inverse of
    the product of its two link lengths, against the shipped one's); 1 for the shipped design
    and any design at or below it (the sizes are then as written: rubbing torques and printed
    links do not get smaller with a softer spring)."""
    ref = _reference()
    span = np.asarray(design.k, float) * design.joint_limit_rad
    ref_span = np.asarray(ref.k, float) * ref.joint_limit_rad
    torque = span / ref_span
    bend = (ref.la_mm * ref.lb_mm) / (design.la_mm * design.lb_mm)
    # Exactly 1 at or below the shipped design: its fits stay bit for bit what they were.
    return np.where(torque > 1.0 + 1e-9, torque, 1.0), bend if bend > 1.0 + 1e-9 else 1.0


def first_order_latency() -> Term:
    """The rig's latency as ``delta6 calibrate`` fits it: the first-order column alone (a
    reference late by tau reads the wrench minus tau dW/dt), with the family's prior on it
    (the second-order column is free enough to pass for another effect beside a fit the
    calibration bounds)."""
    family = next(t for t in TERMS if t.name == "sensor_latency")
    return Term(family.name, family.acts_on, family.param_names[:1], "s",
                _first_order_latency, prior_sd=family.prior_sd[:1],
                plausible=_each([("latency_s", slice(0, 1), LATENCY_LIMIT_S)]))


def for_design(terms, design) -> tuple[Term, ...]:
    """``terms`` with their prior scales and plausibility limits sized for ``design``: the
    torque families' by each joint's spring span, the link compliance's by the link lengths
    (``design_scales``). The shipped design's terms come back unchanged."""
    torque, bend = design_scales(design)
    out = []
    for term in terms:
        if term.name in TORQUE_FAMILIES and np.any(torque != 1.0):
            width = len(term.param_names) // 6
            prior = (np.asarray(term.prior_sd, float).reshape(6, width) * torque[:, None])
            term = dataclasses.replace(
                term, prior_sd=tuple(float(v) for v in prior.ravel()),
                limit_scale=tuple((q, tuple(float(v) for v in torque))
                                  for q in TORQUE_FAMILIES[term.name]))
        elif term.name == "link_compliance" and bend != 1.0:
            prior = np.asarray(term.prior_sd, float)
            prior[COMPLIANCE_PARAMS] *= bend
            term = dataclasses.replace(
                term, prior_sd=tuple(float(v) for v in prior),
                limit_scale=tuple((q, (bend,)) for q in COMPLIANCE_QUANTITIES))
        out.append(term)
    return tuple(out)
