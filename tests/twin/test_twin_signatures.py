"""Each effect leaves the signature its physics says, in the analytical model's residual
(model applied to the logged angles minus the logged reference wrench)."""
from __future__ import annotations

import numpy as np
import pytest

from delta6 import twin
from delta6.core import model
from delta6.core.operators import first_order

from support.twinkit import CLEAN, held_path, residual, reversed_path, sine_path

MX = 3
#: A pose away from the centre, held during the thermal runs.
HELD = [0.3, -0.2, 0.1, 0.25, -0.3, 0.2]


def one(name, **kw):
    return [twin.make_effect(name, 11, **kw)]


def swing(design, effects, *, joint=4, amplitude=0.3, freq_hz=0.1, cycles=2, per_cycle=500,
          measurement=CLEAN, base=0.0):
    """``cycles`` sine cycles on one joint, always ``per_cycle`` samples per cycle: slow and fast
    runs then sample the same phases."""
    return twin.simulate(design, effects, duration_s=cycles / freq_hz,
                         rate_hz=per_cycle * freq_hz, seed=3,
                         path=sine_path(joint, amplitude, freq_hz, base), measurement=measurement)


def moving_up(result, joint=4):
    rate = np.gradient(result.true_angles[:, joint - 1], result.t)
    return rate > 0, rate


def sliding(result, joint=4, travel=0.02):
    """Samples farther than ``travel`` from the last reversal of the joint (past any
    pre-sliding) and moving."""
    q = result.true_angles[:, joint - 1]
    step = np.diff(q, prepend=q[0])
    turns = np.flatnonzero(np.sign(step[1:]) != np.sign(step[:-1])) + 1
    last = np.zeros(len(q), dtype=int)
    last[turns] = turns
    last = np.maximum.accumulate(last)
    return (np.abs(q - q[last]) > travel) & (np.abs(np.gradient(q, result.t)) > 1e-3)


# --- spring_hysteresis: direction of the last motion matters, speed does not ---------------

@pytest.mark.parametrize("formulation", ["bouc_wen", "play_sum"])
def test_hysteresis_depends_on_direction_not_speed(baseline, formulation):
    effect = one("spring_hysteresis", formulation=formulation, half_width_nm=0.01)
    slow = swing(baseline, effect, freq_hz=0.02)
    fast = swing(baseline, effect, freq_hz=0.5)
    r_slow, r_fast = residual(slow)[:, MX], residual(fast)[:, MX]
    assert np.abs(r_slow - r_fast).max() < 1e-9          # same phases, 25x the speed
    # Second cycle (settled loop): at the same angle, loading and unloading differ by ~2H.
    half = len(r_slow) // 2
    q = slow.true_angles[half:, 3]
    up, _ = moving_up(slow)
    up = up[half:]
    mid = np.abs(q) < 0.05
    loading = r_slow[half:][mid & up].mean()
    unloading = r_slow[half:][mid & ~up].mean()
    assert loading < -0.006 and unloading > 0.006        # model misses +-H: residual -+H


# --- joint_friction: grows with speed, flips with direction -------------------------------

@pytest.mark.parametrize("formulation", ["coulomb_viscous", "stribeck", "lugre"])
def test_friction_grows_with_speed_and_flips_with_direction(baseline, formulation):
    # Past the Stribeck dip (friction falls with speed below ~stribeck_rad_s).
    shape = {} if formulation == "coulomb_viscous" else {"stribeck_rad_s": 0.005}
    effect = one("joint_friction", formulation=formulation, coulomb_nm=0.004,
                 viscous_nm_s_per_rad=0.004, **shape)
    slow = swing(baseline, effect, freq_hz=0.02)
    fast = swing(baseline, effect, freq_hz=0.5)
    for result in (slow, fast):
        up, rate = moving_up(result)
        moving = sliding(result)
        r = residual(result)[:, MX]
        # The reference carries the friction torque (+ when moving up); the model misses it.
        assert np.all(np.sign(r[moving]) == -np.sign(rate[moving]))
    # Faster: more friction (viscous), compared at the same phases.
    r_slow, r_fast = np.abs(residual(slow)[:, MX]), np.abs(residual(fast)[:, MX])
    _, rate = moving_up(slow)
    moving = sliding(slow) & (np.abs(rate) > 0.02)
    gain = (r_fast - r_slow)[moving]
    assert np.all(gain > 0)
    assert np.median(gain) > 0.002       # viscous 0.004 N*m*s/rad over ~0.9 rad/s of extra speed


# --- sensor_latency: residual follows dW/dt; shifting the reference back removes it -------

@pytest.mark.parametrize("formulation", ["delay", "first_order"])
def test_latency_residual_follows_wrench_rate(baseline, formulation):
    latency = 0.02
    result = twin.simulate(baseline, one("sensor_latency", formulation=formulation,
                                         latency_s=latency),
                           duration_s=120, rate_hz=50, seed=5, measurement=CLEAN)
    w = result.model_wrench()
    r = w - result.wrench
    rate = np.gradient(w, result.t, axis=0)
    for axis in range(6):
        assert np.corrcoef(r[:, axis], rate[:, axis])[0, 1] > 0.95
    # The reference sampled `latency` later lines up with the angles again.
    later = np.stack([np.interp(result.t + latency, result.t, result.wrench[:, a])
                      for a in range(6)], axis=1)
    inner = slice(5, -5)
    before = np.sqrt(np.mean(r[inner] ** 2, axis=0))
    after = np.sqrt(np.mean((w - later)[inner] ** 2, axis=0))
    assert np.all(after < before / (20 if formulation == "delay" else 4))


# --- backlash: after a reversal the encoder stands still until the play is taken up -------

@pytest.mark.parametrize("formulation", ["dead_zone", "elastic_contact"])
def test_backlash_encoder_stands_still_after_reversal(baseline, formulation):
    play = 0.01
    effect = one("backlash", formulation=formulation, play_rad=play, joints=2)
    result = swing(baseline, effect, joint=2, amplitude=0.2, freq_hz=0.1, cycles=3,
                   per_cycle=2000)
    q, enc = result.true_angles[:, 1], result.theta[:, 1]
    dwell = 2 * effect[0].radii()[:, 1].min()
    peaks = np.flatnonzero(np.diff(np.sign(np.diff(q))) != 0) + 1
    assert len(peaks) >= 4
    step = np.abs(np.diff(q)).max()
    for peak in peaks[1:-1]:
        after = np.arange(peak, len(q))
        moved = np.abs(enc[after] - enc[peak]) > 1e-12
        first = after[np.argmax(moved)]
        travel = abs(q[first] - q[peak])
        # The encoder stands still while the link travels the dwell (to one sample's travel),
        # then lags the link by half the play once picked up.
        assert dwell <= travel <= dwell + step
        assert abs(abs(enc[first + 400] - q[first + 400]) - play / 2) < 1e-9
    # The other joints' encoders read their (constant) angles exactly.
    assert np.all(result.theta[:, [0, 2, 3, 4, 5]] == result.theta[0, [0, 2, 3, 4, 5]])


# --- encoder_offset and geometry_error: functions of the pose, not of the history ---------

@pytest.mark.parametrize("name", ["encoder_offset", "geometry_error", "nonlinear_spring",
                                  "encoder_periodic_error", "harness"])
def test_pose_effects_do_not_depend_on_history(baseline, name):
    effect = one(name, magnitude=0.8)
    duration = 60.0
    forward = twin.simulate(baseline, effect, duration_s=duration, seed=8, measurement=CLEAN)
    backward = twin.simulate(baseline, effect, duration_s=duration, seed=8, measurement=CLEAN,
                             path=reversed_path(forward.path, duration))
    r_f, r_b = residual(forward), residual(backward)
    n = len(r_f)
    assert np.allclose(backward.true_angles[1:], forward.true_angles[::-1][:-1], atol=1e-12)
    # Same pose, same residual (the harness's clamp Jacobian is a finite difference over a
    # 1e-6 rad step, which turns the path's last-bit differences into ~1e-9 N).
    same = 1e-9 if name != "harness" else 1e-8 * np.abs(r_f).max()
    assert np.abs(r_b[1:] - r_f[::-1][:-1]).max() < same
    assert np.all(r_f[:, :3].std(axis=0) > 0.005)               # and it varies with the pose
    assert n == len(r_b)


def test_encoder_offset_is_a_constant_angle_shift(baseline):
    effect = one("encoder_offset", magnitude=1.0)
    result = twin.simulate(baseline, effect, duration_s=30, seed=2, measurement=CLEAN)
    offset = effect[0].p("offset_rad")
    assert np.allclose(result.theta - result.true_angles, offset, atol=1e-15)
    # Knowing the offset explains the whole residual.
    assert np.allclose(model.wrench(baseline, result.theta - offset), result.wrench, atol=1e-9)


# --- stiffness_mismatch: residual proportional to the affected joint's torque --------------

@pytest.mark.parametrize("joint", [2, 5])
def test_stiffness_residual_is_proportional_to_joint_torque(baseline, joint):
    deviation = 0.08
    effect = one("stiffness_mismatch", deviation=deviation, joints=joint)
    result = twin.simulate(baseline, effect, duration_s=60, seed=4, measurement=CLEAN)
    r = residual(result)
    theta = result.theta
    torque = np.zeros_like(theta)
    torque[:, joint - 1] = baseline.k[joint - 1] * theta[:, joint - 1]
    per_joint = model.wrench(baseline, theta, torque=torque)     # the joint's share of W
    coef = np.sum(r * per_joint) / np.sum(per_joint**2)
    assert coef == pytest.approx(-deviation, rel=1e-9)
    assert np.abs(r - coef * per_joint).max() < 1e-9


# --- link_compliance: grows faster than the load (quadratic-ish) ---------------------------

@pytest.mark.parametrize("name,kw,low,high", [
    ("link_compliance", {"formulation": "linear", "magnitude": 1.0}, 0.15, 0.35),
    ("link_compliance", {"formulation": "hertzian", "magnitude": 1.0}, 0.15, 0.4),
    ("stiffness_mismatch", {"magnitude": 0.5}, 0.45, 0.55),      # control: linear in load
])
def test_link_compliance_grows_faster_than_load(baseline, name, kw, low, high):
    def rms_residual(scale):
        result = twin.simulate(baseline, one(name, **kw), duration_s=120, seed=6,
                               measurement=CLEAN, trajectory=twin.TrajectorySettings(scale=scale))
        return np.sqrt(np.mean(residual(result)[:, :3] ** 2, axis=0))
    ratio = rms_residual(0.5) / rms_residual(1.0)
    assert np.all((low < ratio) & (ratio < high)), ratio


# --- thermal_drift: residual follows the temperature -------------------------------------

def test_thermal_residual_follows_temperature(baseline):
    effect = one("thermal_drift", formulation="instant", magnitude=1.0)
    result = twin.simulate(baseline, effect, duration_s=120, seed=9, measurement=CLEAN,
                           path=held_path(HELD))
    assert result.temp_c is not None and np.ptp(result.temp_c) > 5
    r = residual(result)
    for axis in range(6):
        assert abs(np.corrcoef(r[:, axis], result.temp_c)[0, 1]) > 0.99


def test_lagged_thermal_drift_follows_the_device_temperature(baseline):
    effect = one("thermal_drift", formulation="lagged", magnitude=1.0, lag_s=20.0)
    result = twin.simulate(baseline, effect, duration_s=300, seed=9, measurement=CLEAN,
                           path=held_path(HELD))
    r = residual(result)[:, MX]
    a = 20.0 / (20.0 + 1 / 200)
    device = first_order(result.temp_c, a ** 4)
    raw = abs(np.corrcoef(r, result.temp_c)[0, 1])
    lagged = abs(np.corrcoef(r, device)[0, 1])
    assert lagged > raw and lagged > 0.97
