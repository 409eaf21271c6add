"""The twin's statics is the reference model fed with the plant's torques and geometry."""
from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.core import model
from delta6.core.design import load
from delta6.twin.statics import PlantGeometry, link_tension, plant_wrench, rotation_from_vector

from conftest import DESIGNS

DESIGN = load(DESIGNS / "delta6.toml")
P = model.Params.from_design(DESIGN)
angles = arrays(float, (4, 6), elements=st.floats(-0.5, 0.5))


@given(angles)
def test_torque_override_with_spring_torques_is_the_model(theta):
    assert np.allclose(model.wrench(P, theta, torque=P.k * theta), model.wrench(P, theta),
                       rtol=1e-12, atol=1e-12)
    assert np.allclose(plant_wrench(PlantGeometry(P), theta, P.k * theta),
                       model.wrench(P, theta), rtol=1e-12, atol=1e-12)


@given(angles, arrays(float, (4, 6), elements=st.floats(-0.05, 0.05)))
def test_wrench_is_linear_in_the_joint_torques(theta, extra):
    base = model.wrench(P, theta, torque=P.k * theta)
    more = model.wrench(P, theta, torque=P.k * theta + extra)
    only = model.wrench(P, theta, torque=extra)
    assert np.allclose(more - base, only, atol=1e-9)


@given(arrays(float, 3, elements=st.floats(-0.2, 0.2)), angles)
def test_a_turned_gimbal_turns_the_force_only(rotvec, theta):
    r = rotation_from_vector(rotvec)
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(r), 1.0)
    plain = plant_wrench(PlantGeometry(P), theta, P.k * theta)
    turned = plant_wrench(PlantGeometry(P, r), theta, P.k * theta)
    assert np.allclose(turned[:, 3:], plain[:, 3:])
    assert np.allclose(np.linalg.norm(turned[:, :3], axis=1), np.linalg.norm(plain[:, :3], axis=1))


def test_rotation_vector_small_and_exact():
    assert np.allclose(rotation_from_vector(np.zeros(3)), np.eye(3))
    quarter = rotation_from_vector(np.array([0, 0, np.pi / 2]))
    assert np.allclose(quarter @ [1, 0, 0], [0, 1, 0], atol=1e-12)


def test_pulling_the_platform_down_puts_every_link_in_tension():
    theta = np.array([[0.2, 0.2, 0.2, 0, 0, 0]])
    assert model.wrench(P, theta)[0, 2] > 0        # F_z > 0: pulling away from the base
    assert np.all(link_tension(PlantGeometry(P), theta, P.k * theta) > 0)
    # The model's own form defaults to the spring torques (what the diagnosis uses).
    assert np.array_equal(model.link_tension(P, theta[:, :3]),
                          link_tension(PlantGeometry(P), theta, P.k * theta))



@given(angles)
def test_link_tensions_balance_the_platform_force(theta):
    """Eq. (10) from the tensions: each link pulls the platform toward its elbow, along -v."""
    t3 = theta[:, :3]
    v = model.forward_kinematics(P, t3)[:, None, :] - model.branch_centres(P, t3)
    vhat = v / P.lb[:, None]
    pulled = np.sum(-model.link_tension(P, t3)[..., None] * vhat, axis=-2)
    assert np.allclose(pulled, -model.base_force(P, t3), rtol=1e-9, atol=1e-9)


@given(st.floats(-0.3, 0.3), arrays(float, (4, 3), elements=st.floats(-0.5, 0.5)))
def test_the_force_seen_in_a_turned_gimbal_frame_is_the_base_force_turned_back(angle, q123):
    """{E0} turned by R (its orientation in {B}) about z: with the gimbal's joints at rest,
    {E} is {E0}, and the force it reports is R^T times the force in {B} (a frame turned one
    way sees the force turned the other way: a transposed R turns it the wrong way)."""
    theta = np.hstack([q123, np.zeros((4, 3))])
    c, s = np.cos(angle), np.sin(angle)
    r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    assert np.allclose(rotation_from_vector(np.array([0.0, 0.0, angle])), r, atol=1e-12)
    plain = plant_wrench(PlantGeometry(P), theta, P.k * theta)
    turned = plant_wrench(PlantGeometry(P, r), theta, P.k * theta)
    fx, fy = plain[:, 0], plain[:, 1]
    assert np.allclose(turned[:, 0], c * fx + s * fy, atol=1e-9)
    assert np.allclose(turned[:, 1], -s * fx + c * fy, atol=1e-9)
    assert np.allclose(turned[:, 2], plain[:, 2], atol=1e-12)
