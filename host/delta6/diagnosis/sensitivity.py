"""First-order maps of the analytical model, per sample: how the wrench responds to extra joint
torques, to angle errors and to geometry errors. Every candidate effect of the diagnosis is a
perturbation of one of these three kinds, so its wrench signature is linear in its parameters.
"""
from __future__ import annotations

import numpy as np

from delta6.core.model import Params, branch_forces, rotation, wrench


def torque_map(p: Params, theta: np.ndarray) -> np.ndarray:
    """G with W = G(theta) tau for joint torques tau (N*m), shape (n, 6, 6).

    Eqs. (7)-(12) are linear in the joint torques at fixed pose: a unit torque on joint
    i = 1..3 loads its link with v_i / lever_i (eq. 9 with unit torque; the force at {E0} is
    minus that, eq. 10, then R^T), and joints 4..6 add moment components directly. The
    model's wrench is G @ (k * theta_e).
    """
    theta = np.asarray(theta, dtype=float)
    per_torque, _ = branch_forces(p, theta[..., :3], torque123=np.ones(theta.shape[:-1] + (3,)))
    rt = np.swapaxes(rotation(theta[..., 3:]), -1, -2)
    g = np.zeros(theta.shape[:-1] + (6, 6))
    g[..., :3, :3] = -np.einsum("...ij,...kj->...ik", rt, per_torque)
    g[..., 3:, 3:] = rt
    return g


def angle_jacobian(p: Params, theta: np.ndarray, h: float = 1e-6,
                   base: np.ndarray | None = None) -> np.ndarray:
    """dW/dtheta_e by central differences, shape (n, 6 wrench, 6 joints); by forward
    differences from ``base`` (the model's wrench at ``theta``) when given: half the model
    evaluations, a relative error of about h (1e-6), far below anything a log resolves."""
    theta = np.asarray(theta, dtype=float)
    cols = []
    for j in range(6):
        step = np.zeros(6)
        step[j] = h
        if base is None:
            cols.append((wrench(p, theta + step) - wrench(p, theta - step)) / (2 * h))
        else:
            cols.append((wrench(p, theta + step) - base) / h)
    return np.stack(cols, axis=-1)


#: Geometry parameters of the ``geometry_error`` term: (Params field, branch, unit scale to SI).
GEOMETRY_PARAMS = tuple((field, branch, scale) for field, scale in
                        (("a", 1e-3), ("b", 1e-3), ("la", 1e-3), ("lb", 1e-3), ("phi", 1.0))
                        for branch in range(3))
GEOMETRY_NAMES = tuple(f"{field}{branch + 1}_{'mm' if scale == 1e-3 else 'rad'}"
                       for field, branch, scale in GEOMETRY_PARAMS)


def geometry_jacobian(p: Params, theta: np.ndarray, h: float = 1e-7,
                      base: np.ndarray | None = None) -> np.ndarray:
    """dW/d(geometry) by central differences (forward differences from ``base``, the model's
    wrench at ``theta``, when given), per mm for lengths and per rad for azimuths, shape
    (n, 6, 15) in the order of ``GEOMETRY_NAMES``."""
    cols = []
    for field, branch, scale in GEOMETRY_PARAMS:
        nominal = np.array(getattr(p, field), dtype=float)
        up, down = nominal.copy(), nominal.copy()
        up[branch] += h
        down[branch] -= h
        if base is None:
            diff = (wrench(p.with_(**{field: up}), theta)
                    - wrench(p.with_(**{field: down}), theta)) / (2 * h)
        else:
            diff = (wrench(p.with_(**{field: up}), theta) - base) / h
        cols.append(diff * scale)
    return np.stack(cols, axis=-1)
