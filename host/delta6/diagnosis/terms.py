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
==================  ==========  =======================================================

Every term returns *columns*: the wrench change (N, N*m) per unit of each parameter, per
sample, shape (n, 6, p), with the parameters in physical units.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..model import ENCODER_COUNT_RAD, branch_forces
from .data import GapData
from .sensitivity import GEOMETRY_NAMES
from .signals import play_state, smooth_velocity

#: Widths (radius, rad) of the hysteresis play operators: from a few encoder counts... to
#: a third of the joint range. The smallest stays well above the backlash switch so the two
#: families differ in what they can express (a gradual loop vs an instant switch).
HYSTERESIS_RADII = (0.008, 0.02, 0.05, 0.12)
#: Dead band of the backlash direction detector: ignores encoder flicker of +-1 count.
BACKLASH_SWITCH_RAD = 1.5 * ENCODER_COUNT_RAD
#: Velocity scale of the smooth Coulomb sign, rad/s (above the velocity noise of 14-bit
#: encoders differenced at 50 Hz, about 0.02 rad/s).
FRICTION_VELOCITY_RAD_S = 0.03

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

    def summarize(self, coef: np.ndarray) -> dict:
        out = {name: float(v) for name, v in zip(self.param_names, coef)}
        if self.summary is not None:
            out.update(self.summary(np.asarray(coef, dtype=float)))
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


def _geometry(data: GapData) -> np.ndarray:
    return data.geometry_jacobian


def _hysteresis(data: GapData) -> np.ndarray:
    # Torque per N*m of loop half-height, for each play width.
    return _torque_columns(data, play_state(data.theta, HYSTERESIS_RADII))


def _friction(data: GapData) -> np.ndarray:
    vel = smooth_velocity(data.theta, data.t)
    feats = np.stack([np.tanh(vel / FRICTION_VELOCITY_RAD_S), vel], axis=-1)
    return _torque_columns(data, feats)


def _backlash(data: GapData) -> np.ndarray:
    # Moving up, the encoder trails the link by play/2: true angle = encoder + play/2 * dir.
    direction = play_state(data.theta, [BACKLASH_SWITCH_RAD])[:, :, 0]
    return data.angle_jacobian * (0.5 * direction)[:, None, :]


def _compliance(data: GapData) -> np.ndarray:
    # Axial: each distal link stretches by c * (its force); bending: each proximal link's tip
    # moves as if the joint turned by c * (its torque), without changing the spring torque.
    _, lever = branch_forces(data.params, data.theta[:, :3])
    tension = -data.params.k[:3] * data.theta[:, :3] / lever       # signed link force, N
    dlb = data.geometry_jacobian[:, :, 9:12] * 1e3                 # per m of lb_i
    axial = dlb * tension[:, None, :]                               # per (m/N)
    kinematic = data.angle_jacobian[:, :, :3] - data.torque_map[:, :, :3] * data.params.k[:3]
    bending = kinematic * (data.params.k[:3] * data.theta[:, :3])[:, None, :]   # per rad/(N*m)
    return np.concatenate([axial * 1e-6, bending], axis=-1)        # axial in um/N


def _latency(data: GapData) -> np.ndarray:
    # Reference(t) = true(t - tau) ~ true - tau dW/dt + tau^2/2 d2W/dt2.
    d1 = np.gradient(data.model, data.t, axis=0)
    d2 = np.gradient(d1, data.t, axis=0)
    return np.stack([-d1, 0.5 * d2], axis=-1)


def _hysteresis_summary(coef: np.ndarray) -> dict:
    # After a reversal larger than every play width the loop's branches are sum(w) apart on
    # either side: the half-width of the torque loop at the joint.
    w = coef.reshape(6, len(HYSTERESIS_RADII))
    return {"loop_half_width_nm": w.sum(axis=1).tolist()}


def _friction_summary(coef: np.ndarray) -> dict:
    c = coef.reshape(6, 2)
    return {"coulomb_nm": c[:, 0].tolist(), "viscous_nms_per_rad": c[:, 1].tolist()}


def _thermal(data: GapData) -> np.ndarray:
    dt = (data.temp_c - data.temp_c.mean())[:, None, None]
    return np.concatenate([_stiffness(data) * dt, _encoder_offset(data) * dt], axis=-1)


TERMS: tuple[Term, ...] = (
    Term("encoder_offset", "angle", tuple(f"offset_{j}_rad" for j in JOINTS), "rad",
         _encoder_offset),
    Term("stiffness_mismatch", "torque", tuple(f"k_ratio_error_{j}" for j in JOINTS), "1",
         _stiffness),
    Term("geometry_error", "geometry", GEOMETRY_NAMES, "mm or rad", _geometry),
    Term("spring_hysteresis", "torque",
         tuple(f"play_{j}_r{r:g}_nm" for j in JOINTS for r in HYSTERESIS_RADII), "N*m",
         _hysteresis, summary=_hysteresis_summary),
    Term("joint_friction", "torque",
         tuple(f"{kind}_{j}" for j in JOINTS for kind in ("coulomb_nm", "viscous_nms_per_rad")),
         "N*m, N*m*s/rad", _friction, summary=_friction_summary),
    Term("backlash", "angle", tuple(f"play_{j}_rad" for j in JOINTS), "rad", _backlash),
    Term("link_compliance", "geometry",
         tuple(f"axial_b{i}_um_per_n" for i in (1, 2, 3))
         + tuple(f"bending_j{i}_rad_per_nm" for i in (1, 2, 3)), "um/N, rad/(N*m)", _compliance),
    Term("sensor_latency", "time", ("latency_s", "latency_sq_s2"), "s, s^2", _latency),
    Term("thermal_drift", "angle, k",
         tuple(f"k_ratio_per_degc_{j}" for j in JOINTS)
         + tuple(f"offset_per_degc_{j}_rad" for j in JOINTS), "1/degC, rad/degC", _thermal,
         needs_temperature=True),
)
TERM_BY_NAME = {t.name: t for t in TERMS}
EFFECT_NAMES = tuple(t.name for t in TERMS)
