"""Payload compensation: the least-squares estimate recovers a tool exactly from noise-free
wrenches, subtracts its weight at any new orientation, and refuses orientations that do not
determine it."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.core import payload

unit = arrays(float, 4, elements=st.floats(-1, 1)).filter(lambda q: np.linalg.norm(q) > 0.1)


def rotation(q) -> np.ndarray:
    """A rotation matrix from a (non-normalised) quaternion w, x, y, z."""
    w, x, y, z = np.asarray(q) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def measure(mass, com, f0, m0, rotations):
    """What the sensor reads: the weight and its moment about the origin, plus offsets —
    computed directly with vectors, not with the estimator's matrices."""
    out = []
    for r in rotations:
        weight = mass * (r.T @ payload.DOWN)
        out.append(np.concatenate([weight + f0, np.cross(com, weight) + m0]))
    return np.array(out)


tools = st.tuples(st.floats(0.05, 5.0), arrays(float, 3, elements=st.floats(-0.2, 0.2)),
                  arrays(float, 3, elements=st.floats(-5, 5)),
                  arrays(float, 3, elements=st.floats(-0.5, 0.5)))


def spread(rotations) -> float:
    """How far apart the gravity directions are: the second singular value of the unit
    directions about their mean (0 when at most two distinct directions)."""
    g = np.array([r.T @ payload.DOWN for r in rotations]) / payload.STANDARD_GRAVITY
    return float(np.linalg.svd(g - g.mean(0), compute_uv=False)[1])


@given(tools, st.lists(unit, min_size=3, max_size=12), unit)
def test_recovers_the_tool_and_cancels_its_weight_anywhere(tool, quats, later):
    mass, com, f0, m0 = tool
    rotations = [rotation(q) for q in quats]
    assume(spread(rotations) > 0.2)
    est = payload.estimate(measure(mass, com, f0, m0, rotations), rotations)
    assert est.mass == pytest.approx(mass, rel=1e-9)
    assert np.allclose(est.com, com, atol=1e-9)
    assert np.allclose(est.force_offset, f0, atol=1e-9) and np.allclose(est.torque_offset, m0, atol=1e-9)
    assert est.force_rms < 1e-9 and est.torque_rms < 1e-9
    r = rotation(later)
    contact = np.array([1.0, -2.0, 3.0, 0.1, 0.2, -0.3])
    reading = measure(mass, com, f0, m0, [r])[0] + contact
    assert np.allclose(est.compensate(reading, r), contact, atol=1e-8)


@given(tools, st.lists(unit, min_size=2, max_size=6))
def test_a_tared_sensor_needs_two_poses(tool, quats):
    mass, com, *_ = tool
    rotations = [rotation(q) for q in quats]
    g = np.array([r.T @ payload.DOWN for r in rotations]) / payload.STANDARD_GRAVITY
    assume(np.linalg.norm(np.cross(g[0], g[1:]), axis=-1).max() > 0.3)
    est = payload.estimate(measure(mass, com, 0, 0, rotations), rotations, offsets=False)
    assert est.mass == pytest.approx(mass, rel=1e-9) and np.allclose(est.com, com, atol=1e-9)


def test_noise_averages_out():
    rng = np.random.default_rng(3)
    rotations = [rotation(q) for q in rng.normal(size=(40, 4))]
    mass, com = 0.8, np.array([0.01, -0.02, 0.06])
    clean = measure(mass, com, np.zeros(3), np.zeros(3), rotations)
    noisy = clean + rng.normal(size=clean.shape) * np.array([0.02] * 3 + [0.0005] * 3)
    est = payload.estimate(noisy, rotations)
    assert abs(est.mass - mass) < 0.01 and np.abs(est.com - com).max() < 0.003
    assert 0.01 < est.force_rms < 0.03


def test_vectorised_over_many_orientations():
    rng = np.random.default_rng(0)
    rotations = np.array([rotation(q) for q in rng.normal(size=(50, 4))])
    tool = payload.Payload(1.2, np.array([0.0, 0.0, 0.1]), np.zeros(3), np.zeros(3))
    w = tool.gravity_wrench(rotations)
    assert w.shape == (50, 6)
    assert np.allclose(np.linalg.norm(w[:, :3], axis=1), 1.2 * payload.STANDARD_GRAVITY)
    assert np.allclose(tool.compensate(w, rotations), 0, atol=1e-12)


def test_orientations_that_do_not_determine_the_tool_are_refused():
    upright = [np.eye(3)] * 5
    w = measure(1.0, np.array([0.0, 0.0, 0.05]), np.zeros(3), np.zeros(3), upright)
    with pytest.raises(ValueError, match="two poses with different gravity directions"):
        payload.estimate(w, upright)
    tilt = [np.eye(3), rotation([np.cos(0.4), np.sin(0.4), 0, 0]), rotation([np.cos(0.4), 0, np.sin(0.4), 0])]
    two = [np.eye(3), tilt[1], tilt[1], np.eye(3)]          # only two gravity directions
    with pytest.raises(ValueError, match="centre of mass and the offsets: need three poses"):
        payload.estimate(measure(1.0, np.zeros(3), np.zeros(3), np.zeros(3), two), two)
    planar = [np.eye(3), tilt[1], rotation([np.cos(0.8), np.sin(0.8), 0, 0])]   # all about x
    est = payload.estimate(measure(1.0, np.array([0.01, 0.02, 0.03]), np.ones(3), np.ones(3), planar),
                           planar)                        # three directions in a plane suffice
    assert np.allclose(est.com, [0.01, 0.02, 0.03]) and np.allclose(est.torque_offset, 1)
    with pytest.raises(ValueError, match="expected .K, 6. wrenches"):
        payload.estimate(np.zeros((3, 5)), tilt)
    with pytest.raises(ValueError, match="finite"):
        payload.estimate(np.full((3, 6), np.nan), tilt)
