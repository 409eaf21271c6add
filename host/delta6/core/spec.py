"""The parametric design report (the paper's Tables II and III) and the full-scale ranges.

Two ways to evaluate a design over its joint box:

* ``grid_spec(design, n)``: the paper's method, an n-point grid per joint over all six joints
  (n = 10 reproduces the printed tables, artefacts of the even grid included);
* ``converged_spec(design)``: the true extremes over the box, found by :mod:`delta6.core.boxsearch`.

Both exploit the separability of the model: the force at {E} is R(theta4..6)^T F0(theta1..3),
so every pair of a force sample and a rotation sample is one configuration, and the moment
depends on theta4..6 only.
"""
from __future__ import annotations

import functools
from dataclasses import asdict, dataclass

import numpy as np

from delta6.core import boxsearch
from delta6.core.design import Design
from delta6.core.model import (
    ENCODER_COUNT_RAD,
    Params,
    base_force,
    base_moment,
    forward_kinematics,
    rotation,
    wrench,
)
from delta6.core.workspace import joint_box

AXIS_KEYS = ("x", "y", "z")


@dataclass
class Spec:
    """Specification of one design; lengths mm, forces N, torques N*m."""

    method: str
    workspace_mm: list[float]
    workspace_bounds_mm: dict
    force_range_n: dict
    torque_range_nm: dict
    force_norm_max_n: float
    torque_norm_max_nm: float
    force_resolution_n: float
    torque_resolution_nm: float
    full_scale: list[float]

    def as_dict(self) -> dict:
        return asdict(self)


# --- batched pieces of the model over separable samples ------------------------------------

def _pair_extremes(rot: np.ndarray, f0: np.ndarray, chunk: int = 1024):
    """min and max over all (rotation, force) pairs of each component of R^T F0."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(3):
        column = rot[:, :, i]                 # (R^T F0)_i = R[:, i] . F0
        for start in range(0, len(rot), chunk):
            comp = column[start:start + chunk] @ f0.T
            lo[i] = min(lo[i], comp.min())
            hi[i] = max(hi[i], comp.max())
    return lo, hi


def _rotation_step_extreme(rot: np.ndarray, rot_step: np.ndarray, f0: np.ndarray,
                           chunk: int = 2048) -> float:
    """max over pairs of ||(R'^T - R^T) F0||: the force change from one count on joint 4..6."""
    diff = rot_step - rot
    gram = np.einsum("rji,rjk->rik", diff, diff)    # ||D^T F0||^2 = F0 . (D D^T) F0
    # The quadratic form has six distinct terms: one matrix product over all pairs.
    a, b = np.triu_indices(3)
    weights = np.where(a == b, 1.0, 2.0)
    coeffs = gram[:, a, b] * weights                 # (n_rot, 6)
    monomials = f0[:, a] * f0[:, b]                  # (n_force, 6)
    best = 0.0
    for start in range(0, len(coeffs), chunk):
        best = max(best, float((coeffs[start:start + chunk] @ monomials.T).max()))
    return float(np.sqrt(max(best, 0.0)))


def grid_spec(design: Design, n: int) -> Spec:
    """The paper's evaluation: ``n`` evenly spaced angles per joint over the joint box."""
    if n < 2:
        raise ValueError("grid needs at least 2 points per joint")
    p = Params.from_design(design)
    lo, hi = joint_box(design, 3)
    t3 = boxsearch.grid(lo, hi, n)
    pos = forward_kinematics(p, t3) * 1e3
    f0 = base_force(p, t3)
    rot = rotation(t3)
    m0 = base_moment(p, t3)
    moment = np.einsum("rji,rj->ri", rot, m0)
    flo, fhi = _pair_extremes(rot, f0)

    d = ENCODER_COUNT_RAD
    fres = 0.0
    mres = 0.0
    for j in range(3):
        step = t3.copy()
        step[:, j] += d
        fres = max(fres, float(np.linalg.norm(base_force(p, step) - f0, axis=-1).max()))
        rot_step = rotation(step)
        fres = max(fres, _rotation_step_extreme(rot, rot_step, f0))
        moment_step = np.einsum("rji,rj->ri", rot_step, base_moment(p, step))
        mres = max(mres, float(np.linalg.norm(moment_step - moment, axis=-1).max()))
    return _spec(design, f"grid {n}", pos, flo, fhi, moment.min(0), moment.max(0),
                 float(np.linalg.norm(f0, axis=-1).max()),
                 float(np.linalg.norm(m0, axis=-1).max()), fres, mres)


def converged_spec(design: Design) -> Spec:
    """The true extremes over the joint box (stable to far more than 4 significant digits)."""
    return _converged(design)


@functools.lru_cache(maxsize=32)
def _converged(design: Design) -> Spec:
    p = Params.from_design(design)
    lo3, hi3 = joint_box(design, 3)
    lo6, hi6 = joint_box(design, 6)
    d = ENCODER_COUNT_RAD

    def extreme(f, lo, hi, sign, **kw):
        value, _ = boxsearch.maximize(lambda t: sign * f(t), lo, hi, **kw)
        return sign * value

    # Workspace of P (joints 1..3).
    pos_lo, pos_hi = [], []
    for axis in range(3):
        comp = lambda t, a=axis: forward_kinematics(p, t)[:, a]
        pos_lo.append(extreme(comp, lo3, hi3, -1.0))
        pos_hi.append(extreme(comp, lo3, hi3, +1.0))
    pos = np.array([pos_lo, pos_hi]) * 1e3

    # Force components over the 6-D box, seeded with separable pairs.
    seed3 = boxsearch.grid(lo3, hi3, 9)
    seed_f0 = base_force(p, seed3)
    seed_rot = rotation(seed3)

    def force(t6):
        return wrench(p, t6)[:, :3]

    def seeded_extreme(f, seed_values, sign):
        # seed_values: (n_rot, n_force) values of f on the separable seed pairs.
        flat = sign * seed_values.reshape(-1)
        top = np.argsort(flat)[::-1][:8]
        r_idx, f_idx = np.unravel_index(top, seed_values.shape)
        starts = np.concatenate([seed3[f_idx], seed3[r_idx]], axis=1)
        value, _ = boxsearch.maximize(lambda t: sign * f(t), lo6, hi6, seeds=1,
                                      starts=len(starts), extra_starts=starts)
        return sign * value

    flo, fhi = [], []
    for axis in range(3):
        seed_vals = np.einsum("rj,fj->rf", seed_rot[:, :, axis], seed_f0)
        comp = lambda t, a=axis: force(t)[:, a]
        flo.append(seeded_extreme(comp, seed_vals, -1.0))
        fhi.append(seeded_extreme(comp, seed_vals, +1.0))

    def moment(t3):
        return np.einsum("nji,nj->ni", rotation(t3), base_moment(p, t3))

    mlo, mhi = [], []
    for axis in range(3):
        comp = lambda t, a=axis: moment(t)[:, a]
        mlo.append(extreme(comp, lo3, hi3, -1.0))
        mhi.append(extreme(comp, lo3, hi3, +1.0))

    fnorm = extreme(lambda t: np.linalg.norm(base_force(p, t), axis=-1), lo3, hi3, 1.0)
    mnorm = extreme(lambda t: np.linalg.norm(base_moment(p, t), axis=-1), lo3, hi3, 1.0)

    # Resolution: one encoder count on one joint at a time, worst case over the box.
    fres = 0.0
    for j in range(3):
        step_fn = lambda t, j=j: np.linalg.norm(base_force(p, _bump(t, j, d)) - base_force(p, t),
                                                axis=-1)
        fres = max(fres, extreme(step_fn, lo3, hi3, 1.0))
    mres = 0.0
    for j in range(3):
        seed_step = rotation(_bump(seed3, j, d)) - seed_rot
        seed_vals = np.linalg.norm(np.einsum("rji,fj->rfi", seed_step, seed_f0), axis=-1)

        def rot_step(t6, j=j):
            diff = rotation(_bump(t6[:, 3:], j, d)) - rotation(t6[:, 3:])
            return np.linalg.norm(np.einsum("nji,nj->ni", diff, base_force(p, t6[:, :3])),
                                  axis=-1)
        fres = max(fres, seeded_extreme(rot_step, seed_vals, 1.0))
        m_step = lambda t, j=j: np.linalg.norm(moment(_bump(t, j, d)) - moment(t), axis=-1)
        mres = max(mres, extreme(m_step, lo3, hi3, 1.0))

    return _spec(design, "converged", pos, np.array(flo), np.array(fhi), np.array(mlo),
                 np.array(mhi), fnorm, mnorm, fres, mres, bounds_given=True)


def _bump(t: np.ndarray, j: int, d: float) -> np.ndarray:
    out = np.array(t, dtype=float, copy=True)
    out[..., j] += d
    return out


def _spec(design, method, pos, flo, fhi, mlo, mhi, fnorm, mnorm, fres, mres,
          bounds_given=False) -> Spec:
    pos_lo, pos_hi = (pos[0], pos[1]) if bounds_given else (pos.min(0), pos.max(0))
    full = full_scale(design) if method != "converged" else _full_scale_from(flo, fhi, mlo, mhi)
    return Spec(
        method=method,
        workspace_mm=[float(v) for v in pos_hi - pos_lo],
        workspace_bounds_mm={k: [float(pos_lo[i]), float(pos_hi[i])]
                             for i, k in enumerate(AXIS_KEYS)},
        force_range_n={k: [float(flo[i]), float(fhi[i])] for i, k in enumerate(AXIS_KEYS)},
        torque_range_nm={k: [float(mlo[i]), float(mhi[i])] for i, k in enumerate(AXIS_KEYS)},
        force_norm_max_n=float(fnorm), torque_norm_max_nm=float(mnorm),
        force_resolution_n=float(fres), torque_resolution_nm=float(mres),
        full_scale=[float(v) for v in full],
    )


def _full_scale_from(flo, fhi, mlo, mhi) -> np.ndarray:
    return np.concatenate([np.maximum(np.abs(flo), np.abs(fhi)),
                           np.maximum(np.abs(mlo), np.abs(mhi))])


def full_scale(design: Design) -> np.ndarray:
    """Full scale of each axis [Fx, Fy, Fz, Mx, My, Mz] (N, N*m): the larger magnitude of the
    axis's converged range limits. Every "% FS" figure in the project divides by this."""
    return np.array(_converged(design).full_scale)
