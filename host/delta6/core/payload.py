"""Payload (tool) gravity compensation: estimate a tool's mass and centre of mass from wrenches
measured at several known orientations, then subtract its weight's wrench at any orientation.

The model, in the sensor's frame (forces N, moments N*m, lengths m), for a sensor at
orientation ``R`` (the rotation that takes sensor-frame vectors to the world frame, as a robot
reports its flange) and gravity ``g`` in the world frame::

    g_s = R^T g                   gravity seen by the sensor
    F   = m g_s + F0              the tool's weight, plus the sensor's force offset
    M   = c x (m g_s) + M0        its moment about the sensor origin, plus the moment offset

Both are linear in the unknowns: ``F`` in (m, F0), ``M`` in (m c, M0) since
``c x (m g_s) = -[g_s]x (m c)``. Least squares over all samples solves them, as robot-side F/T
drivers do. The force needs two orientations with different gravity directions, the moment three
when the offsets are estimated too (two when the sensor was tared without the tool). A sensor
that reports the reaction (the wrench the sensor exerts on the tool) gives a negative mass:
the sign convention is the sensor's.

Example, with a robot reporting ``R`` for each pose::

    from delta6.core import payload
    tool = payload.estimate(wrenches, rotations)       # (K, 6) and (K, 3, 3), K >= 3 poses
    print(tool.mass, tool.com)                          # kg, m in the sensor frame
    contact = tool.compensate(wrench_now, R_now)        # the wrench without the tool's weight
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Standard gravity, m/s^2, pointing down the world's z axis.
STANDARD_GRAVITY = 9.80665
DOWN = np.array([0.0, 0.0, -STANDARD_GRAVITY])


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]x for (..., 3) vectors: (..., 3, 3) with [v]x w = v x w."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = np.zeros_like(x)
    return np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1),
                     np.stack([-y, x, zero], -1)], -2)


def gravity_in_sensor(rotation, gravity=DOWN) -> np.ndarray:
    """g_s = R^T g for rotations of shape (..., 3, 3)."""
    return np.einsum("...ji,j->...i", np.asarray(rotation, float), np.asarray(gravity, float))


@dataclass(frozen=True)
class Payload:
    """A tool's mass (kg) and centre of mass (m, sensor frame), with the sensor's offsets and the
    fit's root-mean-square residuals (N, N*m)."""

    mass: float
    com: np.ndarray
    force_offset: np.ndarray
    torque_offset: np.ndarray
    force_rms: float = 0.0
    torque_rms: float = 0.0

    def gravity_wrench(self, rotation, gravity=DOWN) -> np.ndarray:
        """(..., 6) wrench the tool's weight causes at the sensor (offsets not included)."""
        weight = self.mass * gravity_in_sensor(rotation, gravity)
        return np.concatenate([weight, np.cross(self.com, weight)], axis=-1)

    def compensate(self, wrench, rotation, gravity=DOWN) -> np.ndarray:
        """The measured ``wrench`` (..., 6) without the tool's weight and the sensor's offsets:
        what acts on the tool besides gravity."""
        offsets = np.concatenate([self.force_offset, self.torque_offset])
        return np.asarray(wrench, float) - self.gravity_wrench(rotation, gravity) - offsets


def estimate(wrenches, rotations, gravity=DOWN, offsets: bool = True) -> Payload:
    """Least-squares payload from ``wrenches`` (K, 6) measured at ``rotations`` (K, 3, 3).

    ``offsets=False`` assumes a sensor tared with no tool (F0 = M0 = 0), which needs fewer
    orientations. Raises ValueError naming what the orientations fail to determine."""
    wrenches = np.asarray(wrenches, float)
    rotations = np.asarray(rotations, float)
    if wrenches.ndim != 2 or wrenches.shape[1] != 6 or rotations.shape != (len(wrenches), 3, 3):
        raise ValueError(f"expected (K, 6) wrenches and (K, 3, 3) rotations, got "
                         f"{wrenches.shape} and {rotations.shape}")
    if not np.isfinite(wrenches).all() or not np.isfinite(rotations).all():
        raise ValueError("wrenches and rotations must be finite (drop flagged samples first)")
    k = len(wrenches)
    g_s = gravity_in_sensor(rotations, gravity)                      # (K, 3)
    eye = np.broadcast_to(np.eye(3), (k, 3, 3))
    # Force: F = g_s m + F0.
    a_force = g_s[:, :, None]
    if offsets:
        a_force = np.concatenate([a_force, eye], axis=2)
    x_force, rms_force = _solve(a_force, wrenches[:, :3], "the mass", offsets)
    mass = float(x_force[0])
    # Moment: M = -[g_s]x (m c) + M0.
    a_torque = -_skew(g_s)
    if offsets:
        a_torque = np.concatenate([a_torque, eye], axis=2)
    x_torque, rms_torque = _solve(a_torque, wrenches[:, 3:], "the centre of mass", offsets)
    if mass == 0.0:
        raise ValueError("the estimated mass is zero: the centre of mass is undefined")
    zero = np.zeros(3)
    return Payload(mass=mass, com=x_torque[:3] / mass,
                   force_offset=x_force[1:4] if offsets else zero,
                   torque_offset=x_torque[3:6] if offsets else zero,
                   force_rms=rms_force, torque_rms=rms_torque)


def _solve(a: np.ndarray, b: np.ndarray, what: str, offsets: bool) -> tuple[np.ndarray, float]:
    """Stack the (K, 3, n) blocks into one system; refuse an ill-determined one."""
    n = a.shape[2]
    a2, b2 = a.reshape(-1, n), b.reshape(-1)
    sv = np.linalg.svd(a2, compute_uv=False)
    if sv[-1] <= 1e-6 * sv[0]:
        need = {1: "gravity to act", 6: "three poses with different gravity directions"}.get(
            n, "two poses with different gravity directions")
        raise ValueError(f"the orientations do not determine {what}"
                         f"{' and the offsets' if offsets else ''}: need {need}")
    x, *_ = np.linalg.lstsq(a2, b2, rcond=None)
    rms = float(np.sqrt(np.mean((a2 @ x - b2) ** 2)))
    return x, rms
