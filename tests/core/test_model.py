"""Properties of the analytical reference model (eqs. 1-14)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.core import model
from delta6.core.design import load

from conftest import DESIGN_FILES

LIM = np.pi / 6
angle = st.floats(-LIM, LIM, allow_nan=False)
angles6 = arrays(float, 6, elements=angle)
angles3 = arrays(float, 3, elements=angle)
designs = [load(f) for f in DESIGN_FILES]
design_st = st.sampled_from(designs)

ROT120 = np.array([[np.cos(2 * np.pi / 3), -np.sin(2 * np.pi / 3), 0],
                   [np.sin(2 * np.pi / 3), np.cos(2 * np.pi / 3), 0], [0, 0, 1.0]])


@pytest.mark.parametrize("design", designs, ids=lambda d: d.name)
def test_zero_deflection_gives_zero_wrench(design):
    assert np.array_equal(model.wrench(design, np.zeros(6)), np.zeros(6))


@given(design_st, angles3)
def test_platform_closes_every_link(design, t):
    p = model.Params.from_design(design)
    pos = model.forward_kinematics(p, t)
    v = pos[None, :] - model.branch_centres(p, t)
    assert np.allclose(np.linalg.norm(v, axis=-1), p.lb, rtol=0, atol=1e-12)
    assert pos[2] > 0  # below the base, z_B pointing down


@given(design_st, angles3)
def test_three_branches_are_symmetric_under_120_degrees(design, t):
    turned = np.array([t[2], t[0], t[1]])  # branch i+1 takes branch i's angle
    assert np.allclose(ROT120 @ model.forward_kinematics(design, t),
                       model.forward_kinematics(design, turned), atol=1e-12)
    assert np.allclose(ROT120 @ model.base_force(design, t), model.base_force(design, turned),
                       atol=1e-9)


@given(design_st, arrays(float, 3, elements=st.floats(-0.5, 0.5)))
def test_forward_kinematics_matches_finite_differences_and_virtual_work(design, t):
    """The statics must be the transpose of the kinematics: J^T F0 = k theta_e (virtual work),
    with J the finite-difference Jacobian of the forward kinematics."""
    p = model.Params.from_design(design)
    h = 1e-6
    jac = np.stack([(model.forward_kinematics(p, t + h * e) - model.forward_kinematics(p, t - h * e))
                    / (2 * h) for e in np.eye(3)], axis=-1)
    # First-order consistency: a small step moves P by J dtheta.
    step = np.array([1e-4, -2e-4, 1.5e-4])
    moved = model.forward_kinematics(p, t + step) - model.forward_kinematics(p, t)
    assert np.allclose(moved, jac @ step, atol=1e-9)
    torque = jac.T @ model.base_force(p, t)
    assert np.allclose(torque, p.k[:3] * t, atol=1e-6 * max(1.0, np.abs(p.k[:3] * t).max()))


@given(design_st, angles6, st.floats(0.1, 10.0))
def test_wrench_is_linear_in_k(design, t, scale):
    p = model.Params.from_design(design)
    scaled = p.with_(k=p.k * scale)
    assert np.allclose(model.wrench(scaled, t), scale * model.wrench(p, t), rtol=1e-12, atol=1e-12)


@given(design_st, angles6, arrays(float, 6, elements=st.floats(0.2, 3.0)))
def test_per_joint_k_scales_each_joint_alone(design, t, ks):
    """F depends on k1..3 through the joint torques, M on k4..6 only: linear superposition."""
    p = model.Params.from_design(design).with_(k=ks)
    w = model.wrench(p, t)
    # The same pose with only joint j's spring: the contributions must add up to the whole.
    parts = [model.wrench(p.with_(k=np.where(np.arange(6) == j, ks, 0.0)), t) for j in range(6)]
    assert np.allclose(sum(parts), w, atol=1e-9)


@given(design_st, angles6)
def test_rotation_is_zxy_euler_and_orthonormal(design, t):
    r = model.rotation(t[3:])
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(r), 1.0)

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    assert np.allclose(r, rz(t[5]) @ rx(t[3]) @ ry(t[4]), atol=1e-12)


@given(design_st, angles6)
def test_force_norm_is_invariant_under_the_gimbal(design, t):
    w = model.wrench(design, t)
    assert np.isclose(np.linalg.norm(w[:3]), np.linalg.norm(model.base_force(design, t[:3])))
    assert np.isclose(np.linalg.norm(w[3:]), np.linalg.norm(design.k[3:] * t[3:]))


def test_batch_shapes_broadcast(baseline):
    rng = np.random.default_rng(0)
    t = rng.uniform(-LIM, LIM, (4, 5, 6))
    w = model.wrench(baseline, t)
    assert w.shape == (4, 5, 6)
    single = np.array([[model.wrench(baseline, t[i, j]) for j in range(5)] for i in range(4)])
    assert np.allclose(w, single, rtol=0, atol=1e-13)


def test_per_sample_parameters_broadcast(baseline):
    """The twin varies k per sample (thermal drift): params with a batch shape broadcast."""
    rng = np.random.default_rng(1)
    t = rng.uniform(-LIM, LIM, (7, 6))
    p = model.Params.from_design(baseline)
    ks = p.k * rng.uniform(0.9, 1.1, (7, 1))
    batched = model.wrench(p.with_(k=ks), t)
    one_by_one = np.array([model.wrench(p.with_(k=ks[i]), t[i]) for i in range(7)])
    assert np.allclose(batched, one_by_one, atol=1e-13)


def test_known_pose_matches_hand_computation(baseline):
    """A single joint deflected, computed from the paper's equations by hand (independent
    trilateration: symmetric pose, P on the axis)."""
    p = model.Params.from_design(baseline)
    pos = model.forward_kinematics(p, np.zeros(3))
    theta = np.pi / 6
    radial = 0.072 - 0.02124 + 0.040 * np.cos(theta)
    assert np.allclose(pos[:2], 0, atol=1e-15)
    assert np.isclose(pos[2], 0.040 * np.sin(theta) + np.sqrt(0.120**2 - radial**2), atol=1e-15)
    # Equal deflection of joints 1..3 pushes purely along z.
    f = model.base_force(p, np.full(3, 0.2))
    assert np.allclose(f[:2], 0, atol=1e-12) and abs(f[2]) > 1


def test_no_solution_is_nan_not_garbage(baseline):
    p = model.Params.from_design(baseline).with_(lb=np.full(3, 0.02))
    pos, z2 = model.forward_kinematics(p, np.zeros(3), return_disc=True)
    assert z2 < 0 and np.isnan(pos).all()


@given(arrays(float, 6, elements=st.floats(-50, 50)),
       arrays(float, 3, elements=st.floats(-np.pi, np.pi)),
       arrays(float, 3, elements=st.floats(-0.2, 0.2)))
def test_eq14_round_trip(w_t, euler, p_t):
    r_te = model.rotation(euler)
    w_e = model.sensor_to_e(w_t, r_te, p_t)
    assert np.allclose(model.e_to_sensor(w_e, r_te, p_t), w_t, atol=1e-9)


def test_eq14_moves_the_moment_by_the_lever_arm():
    """A pure force through the {T} origin shows up at {E} with moment -p x F (eq. 14)."""
    f_t = np.array([0.0, 0.0, -10.0])
    p_t = np.array([0.05, 0.0, 0.0])
    w_e = model.sensor_to_e(np.concatenate([f_t, np.zeros(3)]), np.eye(3), p_t)
    assert np.allclose(w_e, [0, 0, -10, 0, -0.5, 0])
