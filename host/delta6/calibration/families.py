"""The calibration's parameter families: for each correctable effect, how the calibrated model's
wrench changes per unit of each of its parameters (columns, linear around the current
calibration) and how a fitted step updates the calibration.

The columns use the diagnosis's per-sample maps of the analytical model (``G``: joint torques
to wrench, ``J = dW/dtheta``, ``dW/d(geometry)``) and the calibrated model's own *causal*
history features (``delta6.core.calibrated``), so what is fitted is exactly what the board
computes. Each family returns columns (n, 6, p) in the units of its parameters.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from delta6.core import model
from delta6.core.calibrated import JointTerms
from delta6.core.calibration import Calibration
from delta6.diagnosis.data import GapData
from delta6.diagnosis.terms import force_rotation


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
    on_device: bool = True


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


def _geometry(ctx):
    d = ctx.data
    return np.concatenate([d.geometry_jacobian, _kinematic(ctx)[:, :, :3],
                           force_rotation(d, np.ones((ctx.n, 3)))], axis=-1)


def _hysteresis(ctx):
    return _torque(ctx, ctx.terms.hysteresis)


def _friction(ctx):
    t = ctx.terms
    speeds = ctx.cal.friction_speeds_rad_s
    feats = [np.clip(t.speed / v, -1.0, 1.0) for v in speeds] + [t.speed, t.direction]
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


JOINTS = tuple(f"j{i}" for i in range(1, 7))
BRANCHES = tuple(f"b{i}" for i in range(1, 4))


def families(cal: Calibration) -> dict[str, Family]:
    """The families for a calibration's settings (radii and speeds fix their widths)."""
    radii = cal.hysteresis_radii_counts
    speeds = cal.friction_speeds_rad_s
    geometry_names = tuple(f"delta_{k}_{b}_mm" for k in ("a", "b", "la", "lb") for b in BRANCHES) \
        + tuple(f"delta_azimuth_{b}_rad" for b in BRANCHES) \
        + tuple(f"delta_rest_angle_{b}_rad" for b in BRANCHES) \
        + tuple(f"gimbal_misalignment_{a}_rad" for a in "xyz")
    return {f.effect: f for f in (
        Family("encoder_offset", tuple(f"offset_{j}_rad" for j in JOINTS), _offset,
               lambda c, x: _add(c, offset_rad=x)),
        Family("stiffness_mismatch", tuple(f"rate_ratio_{j}" for j in JOINTS), _rate,
               lambda c, x: _add(c, rate_ratio=x)),
        Family("geometry_error", geometry_names, _geometry, _apply_geometry),
        Family("spring_hysteresis", tuple(f"hysteresis_{j}_r{r}_nm" for j in JOINTS for r in radii),
               _hysteresis, lambda c, x: _add(c, hysteresis_nm=x.reshape(6, -1))),
        Family("joint_friction", tuple(f"{k}_{j}" for j in JOINTS for k in
                                       tuple(f"sign_v{v:g}_nm" for v in speeds)
                                       + ("viscous_nm_s_per_rad", "presliding_nm")),
               _friction, _apply_friction),
        Family("backlash", tuple(f"backlash_play_{j}_rad" for j in JOINTS), _backlash,
               lambda c, x: _add(c, backlash_play_rad=x)),
        Family("link_compliance", tuple(f"elbow_{b}_rad_per_nm" for b in BRANCHES)
               + ("tilt_rad_per_nm",), _compliance,
               lambda c, x: _add(c, elbow_rad_per_nm=x[:3]).with_(
                   tilt_rad_per_nm=float(c.tilt_rad_per_nm + x[3]))),
    )}
