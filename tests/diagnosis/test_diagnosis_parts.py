"""Building blocks of the gap diagnosis: history operators, sensitivity maps, selection."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.core import model
from delta6.diagnosis import selection, sensitivity
from delta6.diagnosis.data import GapData
from delta6.diagnosis.signals import play_state, smooth_velocity
from delta6.diagnosis.terms import TERMS

from support.logs import synthetic_log


def test_play_state_saturates_after_a_long_move():
    x = np.concatenate([np.linspace(0, 1, 50), np.linspace(1, 0.5, 50)])[:, None]
    s = play_state(x, [0.1])[:, 0, 0]
    assert s[49] == pytest.approx(1.0) and s[-1] == pytest.approx(-1.0)


def test_smooth_velocity_of_a_ramp_is_exact():
    t = np.arange(100) * 0.02
    x = np.stack([0.3 * t, -2 * t], axis=1)
    assert np.allclose(smooth_velocity(x, t), [0.3, -2.0])


def test_smooth_velocity_window_follows_the_rate_and_falls_back_to_a_line_on_slow_logs():
    x = np.random.default_rng(3).normal(size=(400, 2)).cumsum(axis=0)
    # 50 Hz: a cubic over +-0.2 s (10 samples either side), exact on a cubic.
    t = np.arange(400) * 0.02
    assert np.array_equal(smooth_velocity(x, t), smooth_velocity(x, t, 10, degree=3))
    cubic = np.stack([t**3, -t**3 + t], axis=1)
    assert np.allclose(smooth_velocity(cubic, t)[10:-10], np.stack(
        [3 * t**2, -3 * t**2 + 1], axis=1)[10:-10])
    # 10 Hz: +-0.2 s is two samples, where a cubic's slope is noisier than a line's.
    t = np.arange(400) * 0.1
    assert np.array_equal(smooth_velocity(x, t), smooth_velocity(x, t, 2, degree=1))
    with pytest.raises(ValueError, match="half width"):
        smooth_velocity(x, t, 0)


angles = arrays(float, (4, 6), elements=st.floats(-0.5, 0.5))


@given(angles)
def test_torque_map_reproduces_the_model(baseline_params, theta):
    g = sensitivity.torque_map(baseline_params, theta)
    w = np.einsum("nij,nj->ni", g, baseline_params.k * theta)
    assert np.allclose(w, model.wrench(baseline_params, theta), atol=1e-9)


@given(angles)
def test_angle_jacobian_splits_into_torque_and_kinematic_parts(baseline_params, theta):
    """dW/dtheta_j = G_j k_j + (dG/dtheta_j) tau: the moment rows of joints 4..6 and the
    torque part must agree with the torque map."""
    jac = sensitivity.angle_jacobian(baseline_params, theta)
    g = sensitivity.torque_map(baseline_params, theta)
    # Joints 1..3 do not move the gimbal: their moment rows are zero in both.
    assert np.allclose(jac[:, 3:, :3], 0, atol=1e-6)
    # At zero load the kinematic part vanishes: J = G k.
    zero = np.zeros((1, 6))
    assert np.allclose(sensitivity.angle_jacobian(baseline_params, zero),
                       sensitivity.torque_map(baseline_params, zero) * baseline_params.k,
                       atol=1e-6)
    assert np.isfinite(jac).all() and np.isfinite(g).all()


@pytest.fixture(scope="module")
def baseline_params(baseline):
    return model.Params.from_design(baseline)


@pytest.mark.parametrize("kind", ["none", "stiffness_mismatch", "encoder_offset"])
def test_selection_names_an_injected_error_and_nothing_on_clean_data(baseline, kind):
    data = GapData.from_log(synthetic_log(baseline, kind), baseline)
    terms = [t for t in TERMS if t.available(data)]
    problem = selection.build_problem(data, terms)
    ladder, _ = selection.greedy(problem, [t.name for t in terms], np.random.default_rng(0))
    assert [s.added for s in ladder] == ([] if kind == "none" else [kind])


def test_fitted_stiffness_ratios_are_recovered(baseline):
    data = GapData.from_log(synthetic_log(baseline, "stiffness_mismatch"), baseline)
    problem = selection.build_problem(data, [t for t in TERMS if t.name == "stiffness_mismatch"])
    coef = selection.fit(problem, ["stiffness_mismatch"])
    assert np.allclose(coef, [0.05, -0.03, 0.02, 0.04, -0.04, 0.03], atol=2e-3)


def test_heldout_scoring_never_sees_its_own_block(baseline):
    """A term fitted on pure noise must not look better held-out than not fitting at all."""
    data = GapData.from_log(synthetic_log(baseline, "none"), baseline)
    problem = selection.build_problem(data, list(TERMS[:4]))
    base = selection.heldout_block_sse(problem, [])
    for t in TERMS[:4]:
        assert selection.gain(base, selection.heldout_block_sse(problem, [t.name])) < 0.01


@given(arrays(float, 3, elements=st.floats(-60.0, 60.0)),
       arrays(float, (3, 3), elements=st.floats(-0.03, 0.03)))
def test_the_clamp_offset_follows_from_the_affine_fit(clamp, mix):
    # A force that follows the clamp's displacement, stiffness A (N/mm): per gimbal angle at
    # rest it changes by A (e_i x c), the clamp's motion per angle turning about axis i.
    from delta6.diagnosis.terms import HARNESS_AFFINE, harness_clamp
    stiff = np.diag([0.3, 0.2, 0.1]) + mix
    motion = np.stack([np.cross(e, clamp) for e in np.eye(3)], axis=1)     # mm/rad
    f = np.zeros((7, 3))
    f[1:4] = stiff.T
    f[4:7] = (stiff @ motion).T
    coef = f.ravel()
    assert len(coef) == HARNESS_AFFINE
    assert np.allclose(harness_clamp(coef), clamp, atol=1e-3 * (1 + np.abs(clamp).max()))


def test_the_velocity_fits_a_log_chooses_among_follow_its_rate():
    from delta6.diagnosis.terms import velocity_windows
    assert velocity_windows(0.02) == [(2, 1), (5, 3), (10, 3)]        # 50 Hz
    assert velocity_windows(0.001) == [(2, 1), (50, 3), (100, 3), (200, 3)]    # 1 kHz
    assert velocity_windows(0.1) == [(2, 1)]                          # 10 Hz: the line only


@pytest.mark.slow   # four twin runs of 240 s
@pytest.mark.parametrize("seed", [11, 21])
def test_a_faster_motion_makes_the_friction_choose_a_shorter_velocity_fit(baseline, seed):
    """On the rig's slow moves and dither the cubic over +-0.2 s wins; under a dither of 1 to
    4 Hz and moves of 0.5-3 s it bends the speed, and a shorter fit is chosen."""
    from delta6 import twin
    from delta6.diagnosis.data import GapData
    from delta6.diagnosis.terms import friction_velocity_window
    from delta6.link.logfile import LogData
    from delta6.twin.trajectory import TrajectorySettings

    def chosen(trajectory):
        effect = twin.make_effect("joint_friction", seed=seed, formulation="stribeck",
                                  magnitude=0.8)
        r = twin.simulate(baseline, [effect], duration_s=240, rate_hz=50.0, seed=seed,
                          trajectory=trajectory)
        data = GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=None),
                                baseline)
        return friction_velocity_window(data)

    assert chosen(TrajectorySettings()) == (10, 3)
    fast = TrajectorySettings(dither_min_hz=1.0, dither_max_hz=4.0, move_min_s=0.5,
                              move_max_s=3.0)
    assert chosen(fast)[0] < 10


def test_backlash_signature_is_the_reversal_dwells_not_encoders_that_never_turn(baseline):
    """Under one-axis pushes most joints hardly turn: their encoders flicker by a count and
    their direction never leaves the switch's dead band, or a joint is held on a count's edge
    after a move and its direction touches the band's end at every flicker. Only the stretch a
    reversal's switch is spread over is backlash's own signature, not every sample of such a
    log."""
    from delta6.diagnosis.terms import ENCODER_COUNT_RAD
    from delta6.link.logfile import LogData
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 40.0, 0.02)
    up = np.clip(t / 15.0, 0.0, 1.0) * 0.2                          # 15 s up, then a hold
    down = np.clip((t - 25.0) / 15.0, 0.0, 1.0) * 0.2               # from 25 s back down
    theta = np.full((len(t), 6), 0.01) + rng.uniform(-0.45, 0.45, (len(t), 6)) * ENCODER_COUNT_RAD
    theta[:, 0] = up - down
    # Joint 2 turns 5 counts in the first second, then is held on a count's edge, flickering.
    edge = (np.floor(0.01 / ENCODER_COUNT_RAD) + 5.5) * ENCODER_COUNT_RAD
    theta[:, 1] = np.where(t < 1.0, 0.01 + t * (edge - 0.01),
                           edge + rng.uniform(-0.45, 0.45, len(t)) * ENCODER_COUNT_RAD)
    theta = np.round(theta / ENCODER_COUNT_RAD) * ENCODER_COUNT_RAD
    wrench = model.wrench(model.Params.from_design(baseline), theta)
    data = GapData.from_log(LogData(t=t, theta=theta, wrench=wrench, temp_c=None), baseline)
    backlash = next(term for term in TERMS if term.name == "backlash")
    mask = backlash.signature(data)
    # The one dwell, just before the link turns back (and the first moves, near where the
    # switches start inside their dead bands): nothing else.
    assert mask[(t > 24.5) & (t < 25.0)].all()
    assert not mask[((t > 2.0) & (t < 24.0)) | (t > 26.0)].any()
    assert mask.sum() <= 3.0 / 0.02
