"""The true plant's statics: joint torques to the wrench at {E}, through the reference model.

The analytical model (``delta6.core.model``) is the only statics in the project. The twin feeds it
the plant's own parameters (per sample where an effect makes them vary) and the plant's joint
torques instead of k*theta_e, and adds the one thing the model has no place for: the gimbal's
neutral frame {E0} rotated relative to {B} (a misaligned 3-DOF unit, a platform tilting
under load).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.core import model


@dataclass
class PlantGeometry:
    """The built mechanism. ``params`` may carry a per-sample batch shape (M, ...);
    ``e0_rotation`` (3, 3) or (M, 3, 3) is the orientation of {E0} in {B} (None: identity)."""

    params: model.Params
    e0_rotation: np.ndarray | None = None

    def rotated(self, rotation: np.ndarray) -> "PlantGeometry":
        """{E0} turned further by ``rotation`` (expressed in {B})."""
        e0 = rotation if self.e0_rotation is None else rotation @ self.e0_rotation
        return PlantGeometry(self.params, e0)


def rotation_from_vector(rotvec: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation by |v| about v/|v|, for (..., 3) vectors."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(rotvec, axis=-1)[..., None, None]
    k = np.zeros(rotvec.shape[:-1] + (3, 3))
    x, y, z = np.moveaxis(rotvec, -1, 0)
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -z, y, -x
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = z, -y, x
    with np.errstate(invalid="ignore", divide="ignore"):
        sinc = np.where(angle > 1e-12, np.sin(angle) / angle, 1.0 - angle**2 / 6)
        cosc = np.where(angle > 1e-12, (1 - np.cos(angle)) / angle**2, 0.5 - angle**2 / 24)
    return np.eye(3) + sinc * k + cosc * (k @ k)


def link_tension(geo: PlantGeometry, q: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """Axial force of each parallelogram link, N, positive in tension, shape (M, 3)
    (``model.link_tension`` in the plant's geometry)."""
    return model.link_tension(geo.params, q[..., :3], torque[..., :3])


def base_force(geo: PlantGeometry, q: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """Eq. (10) for the plant: the force at the platform, in {B}, (M, 3)."""
    return model.base_force(geo.params, q[..., :3], torque123=torque[..., :3])


def plant_wrench(geo: PlantGeometry, q: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """The wrench at {E} that balances the joint torques ``torque`` (M, 6) with the true joint
    deflections ``q`` (M, 6), in the built geometry ``geo``."""
    if geo.e0_rotation is None:
        return model.wrench(geo.params, q, torque=torque)
    f_b = base_force(geo, q, torque)
    f_e0 = np.einsum("...ji,...j->...i", geo.e0_rotation, f_b)          # {B} -> {E0}
    return model.wrench_in_e(q[..., 3:], f_e0, torque[..., 3:])
