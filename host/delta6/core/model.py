"""The analytical model of the paper, eqs. (1)-(14): vectorized numpy reference.

Conventions (``docs/model.md``; they are the ones that reproduce the paper's Tables II/III):

* Frame {B}: origin at the centre of the base triangle, x toward joint 1, branches at azimuths
  phi = 0, 120, 240 deg, **z pointing down toward the tool** (p_z > 0 in the working pose).
* Proximal angle theta_i = theta_ei + theta_offset for i = 1..3; theta_i > 0 turns the link down.
* Base joint i at a*u_i, elbow at (a + la cos theta_i) u_i + la sin theta_i z, platform joint at
  P + b*u_i. P follows by trilateration of the centres (elbow_i - b u_i) with radius lb, taking
  the solution below the base.
* Joints 4..6: R = Rz(theta6) Rx(theta4) Ry(theta5); eq. (12) uses R transposed for both the
  force and the torque; eq. (11) takes k*theta_e4..6 as Cartesian moment components.

Every function takes angle arrays of any batch shape ``(..., n)`` and returns ``(..., m)``.
Per-branch parameters (``Params``) may also carry a batch shape that broadcasts against the
angles: the digital twin uses that for per-sample stiffness or geometry.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from delta6.core.design import Design

#: Nominal branch azimuths phi_1..3 in {B}, radians.
NOMINAL_PHI = np.deg2rad([0.0, 120.0, 240.0])
#: Counts a turn of the 14-bit encoders, and one count in radians.
ENCODER_COUNTS_PER_TURN = 2**14
ENCODER_COUNT_RAD = 2 * np.pi / ENCODER_COUNTS_PER_TURN
AXES = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


@dataclass(frozen=True)
class Params:
    """Model parameters in SI units. Branch arrays have shape (..., 3), ``k`` (..., 6)."""

    a: np.ndarray       # base radius to joint axes, m
    b: np.ndarray       # platform radius, m
    la: np.ndarray      # proximal link length, m
    lb: np.ndarray      # parallelogram link length, m
    phi: np.ndarray     # branch azimuth, rad
    offset: np.ndarray  # theta_offset: proximal angle at zero spring torque, rad
    k: np.ndarray       # spring rates of joints 1..6, N*m/rad
    c: float = 0.0      # P to {E} origin along z_B, m

    @classmethod
    def from_design(cls, design: Design) -> "Params":
        three = np.ones(3)
        return cls(a=design.a_mm * 1e-3 * three, b=design.b_mm * 1e-3 * three,
                   la=design.la_mm * 1e-3 * three, lb=design.lb_mm * 1e-3 * three,
                   phi=NOMINAL_PHI.copy(), offset=design.theta_offset_rad * three,
                   k=design.k.copy(), c=design.c_mm * 1e-3)

    def with_(self, **changes) -> "Params":
        return replace(self, **{k: np.asarray(v, dtype=float) if k != "c" else float(v)
                                for k, v in changes.items()})


def as_params(p: Params | Design) -> Params:
    return p if isinstance(p, Params) else Params.from_design(p)


def branch_centres(p: Params, theta123: np.ndarray) -> np.ndarray:
    """Sphere centres elbow_i - b u_i for the trilateration, shape (..., 3 branches, 3)."""
    theta = theta123 + p.offset
    radial = p.a - p.b + p.la * np.cos(theta)
    cphi, sphi = np.cos(p.phi), np.sin(p.phi)
    return np.stack([radial * cphi, radial * sphi, p.la * np.sin(theta)], axis=-1)


def forward_kinematics(p: Params | Design, theta_e123: np.ndarray, *, return_disc: bool = False):
    """Platform centre P in {B} (m) from the encoder angles of joints 1..3, shape (..., 3).

    Where the three spheres do not meet (no solution), P is NaN; ``return_disc`` also returns
    the squared height z^2 of the trilateration, negative exactly where there is no solution.
    """
    p = as_params(p)
    theta_e123 = np.asarray(theta_e123, dtype=float)
    centres = branch_centres(p, theta_e123)
    c1, c2, c3 = centres[..., 0, :], centres[..., 1, :], centres[..., 2, :]
    lb = np.broadcast_to(p.lb, theta_e123.shape)
    r1, r2, r3 = lb[..., 0], lb[..., 1], lb[..., 2]
    d12 = c2 - c1
    d = np.linalg.norm(d12, axis=-1)
    ex = d12 / d[..., None]
    d13 = c3 - c1
    i = np.einsum("...k,...k->...", ex, d13)
    ey_raw = d13 - i[..., None] * ex
    j = np.linalg.norm(ey_raw, axis=-1)
    ey = ey_raw / j[..., None]
    ez = np.cross(ex, ey)
    # The root on the tool's side of the plane through the centres (z_B down, toward the
    # tool): flip ez so that its z component is positive.
    ez = ez * np.where(ez[..., 2:3] < 0, -1.0, 1.0)
    x = (r1**2 - r2**2 + d**2) / (2 * d)
    y = (r1**2 - r3**2 + i**2 + j**2) / (2 * j) - i * x / j
    z2 = r1**2 - x**2 - y**2
    with np.errstate(invalid="ignore"):
        z = np.sqrt(z2)
    pos = c1 + x[..., None] * ex + y[..., None] * ey + z[..., None] * ez
    return (pos, z2) if return_disc else pos


def rotation(theta_e456: np.ndarray) -> np.ndarray:
    """R = Rz(theta6) Rx(theta4) Ry(theta5), the orientation of {E} in {E0}, shape (..., 3, 3)."""
    theta_e456 = np.asarray(theta_e456, dtype=float)
    c4, c5, c6 = np.moveaxis(np.cos(theta_e456), -1, 0)
    s4, s5, s6 = np.moveaxis(np.sin(theta_e456), -1, 0)
    rows = [
        [c6 * c5 - s6 * s4 * s5, -s6 * c4, c6 * s5 + s6 * s4 * c5],
        [s6 * c5 + c6 * s4 * s5, c6 * c4, s6 * s5 - c6 * s4 * c5],
        [-c4 * s5, s4, c4 * c5],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def branch_forces(p: Params | Design, theta_e123: np.ndarray, position: np.ndarray | None = None,
                  torque123: np.ndarray | None = None):
    """Eqs. (2)-(9): the force each parallelogram link carries, in {B}, shape (..., 3, 3).

    Also returns the eq. (7) lever ``la (v_x sin theta - v_z cos theta)`` per branch, (..., 3):
    where it approaches zero the mechanism is singular and the force is unbounded.
    ``torque123`` (N*m) replaces the spring torques k*theta_e of eq. (8): the digital twin's
    joints carry more than an ideal spring (hysteresis, friction).
    """
    p = as_params(p)
    theta_e123 = np.asarray(theta_e123, dtype=float)
    if position is None:
        position = forward_kinematics(p, theta_e123)
    theta = theta_e123 + p.offset
    v = position[..., None, :] - branch_centres(p, theta_e123)          # eq. (2)
    vhat = v / np.asarray(p.lb)[..., None]                                # eq. (3)
    cphi, sphi = np.cos(p.phi), np.sin(p.phi)
    vx_branch = cphi * vhat[..., 0] + sphi * vhat[..., 1]                 # eqs. (4)-(5)
    lever = p.la * (vx_branch * np.sin(theta) - vhat[..., 2] * np.cos(theta))
    if torque123 is None:
        torque123 = np.asarray(p.k)[..., :3] * theta_e123                  # eq. (8)
    magnitude = torque123 / lever                                          # eq. (7)
    return magnitude[..., None] * vhat, lever                             # eq. (9)


def link_tension(p: Params | Design, theta_e123: np.ndarray,
                 torque123: np.ndarray | None = None) -> np.ndarray:
    """Axial force of each parallelogram link, N, positive in tension, shape (..., 3).

    :func:`branch_forces` gives the force of each link on the platform along v (elbow to
    platform), torque / lever; a link in tension pulls the platform toward the elbow, hence
    the minus sign. ``torque123`` defaults to the spring torques k*theta_e1..3."""
    p = as_params(p)
    theta_e123 = np.asarray(theta_e123, dtype=float)
    if torque123 is None:
        torque123 = np.asarray(p.k)[..., :3] * theta_e123
    _, lever = branch_forces(p, theta_e123, torque123=torque123)
    return -torque123 / lever


def base_force(p: Params | Design, theta_e123: np.ndarray,
               torque123: np.ndarray | None = None) -> np.ndarray:
    """Eq. (10): the force at {E0}, in {B} = {E0} axes, N, shape (..., 3). ``torque123``
    replaces the spring torques k*theta_e1..3 (see :func:`branch_forces`)."""
    forces, _ = branch_forces(p, theta_e123, torque123=torque123)
    return -forces.sum(axis=-2)


def base_moment(p: Params | Design, theta_e456: np.ndarray) -> np.ndarray:
    """Eq. (11): the moment at {E0}, N*m, shape (..., 3)."""
    p = as_params(p)
    return np.asarray(p.k)[..., 3:] * np.asarray(theta_e456, dtype=float)


def wrench(p: Params | Design, theta_e: np.ndarray, torque: np.ndarray | None = None) -> np.ndarray:
    """Eqs. (1)-(13): W = [Fx, Fy, Fz, Mx, My, Mz] in frame {E} from six encoder angles (rad).

    ``theta_e`` has shape (..., 6); the result has the same shape. NaN where the forward
    kinematics has no solution (the design check guarantees a solution inside the joint box).
    ``torque`` (..., 6), N*m, replaces the spring torques k*theta_e of eqs. (8) and (11): the
    wrench that balances given joint torques in the pose ``theta_e``.
    """
    p = as_params(p)
    theta_e = np.asarray(theta_e, dtype=float)
    if torque is None:
        f0 = base_force(p, theta_e[..., :3])
        m0 = base_moment(p, theta_e[..., 3:])
    else:
        torque = np.asarray(torque, dtype=float)
        f0 = base_force(p, theta_e[..., :3], torque[..., :3])
        m0 = np.broadcast_to(torque[..., 3:], f0.shape)
    return wrench_in_e(theta_e[..., 3:], f0, m0)


def wrench_in_e(theta_e456: np.ndarray, force_e0: np.ndarray, moment_e0: np.ndarray
                ) -> np.ndarray:
    """Eq. (12): a force and a moment in {E0} axes expressed in {E}, [R^T F, R^T M], (..., 6)."""
    rt = np.swapaxes(rotation(theta_e456), -1, -2)
    force = np.einsum("...ij,...j->...i", rt, force_e0)
    moment = np.einsum("...ij,...j->...i", rt, moment_e0)
    return np.concatenate([force, moment], axis=-1)


# --- eq. (14): the reference sensor's frame {T} and frame {E} -------------------------------

def sensor_to_e(wrench_t: np.ndarray, r_te: np.ndarray, p_t: np.ndarray) -> np.ndarray:
    """Eq. (14): a wrench measured in {T} expressed at {E}.

    ``r_te`` is the constant rotation from {T} to {E} (E_F = r_te @ T_F), ``p_t`` the
    translation of eq. (14) in {T} coordinates (m). Works on (..., 6) arrays.
    """
    wrench_t = np.asarray(wrench_t, dtype=float)
    f_t, m_t = wrench_t[..., :3], wrench_t[..., 3:]
    f_e = np.einsum("ij,...j->...i", r_te, f_t)
    m_e = np.einsum("ij,...j->...i", r_te, m_t - np.cross(p_t, f_t))
    return np.concatenate([f_e, m_e], axis=-1)


def e_to_sensor(wrench_e: np.ndarray, r_te: np.ndarray, p_t: np.ndarray) -> np.ndarray:
    """The inverse of :func:`sensor_to_e` (what the impedance controller of Sec. IV uses)."""
    wrench_e = np.asarray(wrench_e, dtype=float)
    f_t = np.einsum("ji,...j->...i", r_te, wrench_e[..., :3])
    m_t = np.einsum("ji,...j->...i", r_te, wrench_e[..., 3:]) + np.cross(p_t, f_t)
    return np.concatenate([f_t, m_t], axis=-1)
