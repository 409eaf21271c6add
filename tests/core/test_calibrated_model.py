"""The calibrated model: neutral is the analytical model, streams equal whole runs, it is
causal, its plays stay whole counts, and with a twin unit's true parameters it reproduces the
unit's true wrench."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6 import twin
from delta6.core import calibration as C
from delta6.core import model
from delta6.core.calibrated import CalibratedModel, counts_from_angles
from delta6.core.model import ENCODER_COUNT_RAD
from delta6.core.spec import full_scale


def _path_counts(n=600, seed=3):
    rng = np.random.default_rng(seed)
    steps = rng.integers(-3, 4, size=(n, 6))
    return np.clip(np.cumsum(steps, axis=0), -1300, 1300).astype(float)


def _busy(baseline) -> C.Calibration:
    rng = np.random.default_rng(5)
    return C.neutral(baseline, "busy").with_(
        offset_rad=rng.uniform(-0.01, 0.01, 6), backlash_play_rad=rng.uniform(0, 0.01, 6),
        rate_ratio=rng.uniform(0.9, 1.1, 6), hysteresis_nm=rng.uniform(-0.01, 0.01, (6, 3)),
        friction_sign_nm=rng.uniform(-0.01, 0.01, (6, 2)),
        viscous_nm_s_per_rad=rng.uniform(0, 0.005, 6), presliding_nm=rng.uniform(0, 0.003, 6),
        delta_a_mm=rng.uniform(-0.5, 0.5, 3), delta_b_mm=rng.uniform(-0.5, 0.5, 3),
        delta_la_mm=rng.uniform(-0.5, 0.5, 3), delta_lb_mm=rng.uniform(-1, 1, 3),
        delta_azimuth_rad=rng.uniform(-0.01, 0.01, 3),
        delta_rest_angle_rad=rng.uniform(-0.01, 0.01, 3),
        gimbal_misalignment_rad=rng.uniform(-0.01, 0.01, 3),
        elbow_rad_per_nm=rng.uniform(0, 0.15, 3), tilt_rad_per_nm=0.08,
        speed_lead_s=C.DEFAULT_SPEED_LEAD_S)


def test_neutral_calibration_is_the_analytical_model(baseline):
    counts = _path_counts()
    w, _ = CalibratedModel(baseline, C.neutral(baseline)).run(counts, 0.004)
    np.testing.assert_allclose(w, model.wrench(baseline, counts * ENCODER_COUNT_RAD),
                               rtol=0, atol=1e-9)


@settings(max_examples=25)
@given(st.lists(st.integers(1, 599), max_size=4))
def test_a_stream_fed_in_pieces_equals_the_whole_run(baseline, cuts):
    m = CalibratedModel(baseline, _busy(baseline))
    counts = _path_counts()
    whole, end = m.run(counts, 0.004)
    pieces, state = [], None
    for part in np.split(counts, sorted(set(cuts))):
        if len(part):
            w, state = m.run(part, 0.004, state)
            pieces.append(w)
    np.testing.assert_allclose(np.concatenate(pieces), whole, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.plays, end.plays, atol=0)
    np.testing.assert_allclose(state.lead, end.lead, rtol=0, atol=1e-12)


@settings(max_examples=40)
@given(st.integers(1, 60), st.integers(0, 2**32 - 1), st.sampled_from([0.002, 0.004, 0.02]),
       st.floats(0.0, 0.05), st.floats(0.005, 0.1))
def test_the_led_speed_is_the_speed_plus_its_filtered_acceleration(n, seed, dt, lead, tau):
    """Written out sample by sample: w = a w + (1 - a) / dt (v - v_before) * lead, with the
    acceleration filtered over twice the speed's time constant; the friction's speed v + w."""
    from delta6.core.calibrated import led_speed
    rng = np.random.default_rng(seed)
    v = rng.normal(0.0, 0.3, (n, 6))
    got, w_got = led_speed(v, dt, tau, lead)
    a = 2 * tau / (2 * tau + dt)
    w, before = np.zeros(6), np.zeros(6)
    for i in range(n):
        w = a * w + (1 - a) / dt * (v[i] - before) * lead
        before = v[i]
        np.testing.assert_allclose(got[i], v[i] + w, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(w_got[i], w, rtol=1e-12, atol=1e-12)
    if lead == 0:
        assert np.array_equal(got, v)


@given(st.integers(1, 598), st.integers(-40, 40))
def test_causal_the_future_does_not_change_the_past(baseline, k, bump):
    m = CalibratedModel(baseline, _busy(baseline))
    counts = _path_counts()
    later = counts.copy()
    later[k:] += bump
    a, _ = m.run(counts, 0.02)
    b, _ = m.run(later, 0.02)
    np.testing.assert_array_equal(a[:k], b[:k])


def test_plays_stay_whole_counts(baseline):
    m = CalibratedModel(baseline, _busy(baseline))
    _, state = m.run(_path_counts(), 0.004)
    assert np.all(state.plays == np.round(state.plays))
    assert np.all(state.direction2 == np.round(state.direction2))


def _unit_run(baseline, effects, seed=11, duration=120.0):
    clean = twin.Measurement(force_noise_n=0.0, moment_noise_nm=0.0, quantize=True)
    return twin.simulate(baseline, effects, duration_s=duration, rate_hz=50, seed=seed,
                         measurement=clean)


def test_with_a_units_true_static_parameters_it_gives_the_true_wrench(baseline):
    effects = [twin.make_effect("stiffness_mismatch", 1, magnitude=1.0),
               twin.make_effect("encoder_offset", 1, magnitude=1.0),
               twin.make_effect("geometry_error", 1, magnitude=1.0)]
    run = _unit_run(baseline, effects)
    p = {e.NAME: e.params for e in effects}
    g = p["geometry_error"]
    cal = C.neutral(baseline).with_(
        rate_ratio=1.0 + p["stiffness_mismatch"]["deviation"],
        offset_rad=p["encoder_offset"]["offset_rad"],
        delta_a_mm=g["delta_a_mm"], delta_b_mm=g["delta_b_mm"], delta_la_mm=g["delta_la_mm"],
        delta_lb_mm=g["delta_lb_mm"], delta_azimuth_rad=g["delta_azimuth_rad"],
        delta_rest_angle_rad=g["delta_rest_angle_rad"],
        gimbal_misalignment_rad=g["gimbal_misalignment_rad"])
    fs = full_scale(baseline)
    calibrated = CalibratedModel(baseline, cal).predict(run)
    err = np.percentile(np.abs(calibrated - run.true_wrench) / fs * 100, 99, axis=0)
    before = np.percentile(np.abs(run.model_wrench() - run.true_wrench) / fs * 100, 99, axis=0)
    assert np.all(before > 1.0)
    assert np.all(err < 0.12), err          # one encoder count is about 0.08 % FS


@pytest.mark.parametrize("name,fields", [
    ("backlash", {"backlash_play_rad": "play_rad"}),
    ("link_compliance", None),
])
def test_angle_and_compliance_corrections_point_the_right_way(baseline, name, fields):
    effect = twin.make_effect(name, 2, magnitude=1.0, **(
        {"formulation": "dead_zone"} if name == "backlash" else {"formulation": "linear"}))
    run = _unit_run(baseline, [effect])
    if name == "backlash":
        cal = C.neutral(baseline).with_(backlash_play_rad=effect.params["play_rad"])
    else:
        la = baseline.la_mm * 1e-3
        cal = C.neutral(baseline).with_(
            elbow_rad_per_nm=effect.params["elbow_mm_per_n"] * 1e-3 / la**2,
            tilt_rad_per_nm=float(effect.params["tilt_rad_per_nm"]))
    fs = full_scale(baseline)
    sq = lambda w: float((((w - run.true_wrench) / fs) ** 2).sum())  # noqa: E731
    assert sq(CalibratedModel(baseline, cal).predict(run)) < 0.5 * sq(run.model_wrench())


def test_counts_from_angles_rounds_to_the_encoder_grid():
    theta = np.array([[0.0, 1, -1, 2.49, -2.51, 1365]]) * ENCODER_COUNT_RAD
    assert counts_from_angles(theta).tolist() == [[0, 1, -1, 2, -3, 1365]]


@given(st.integers(1, 6), st.floats(0.1, 0.9), st.integers(0, 5))
@settings(max_examples=25, deadline=None)
def test_the_friction_is_held_beyond_its_speed_limit(baseline, steps, fraction, joint):
    """A joint turning steadily faster than the calibration's speed limit gets the friction it
    had at the limit (the viscous slope is not extrapolated); below the limit, the slope
    acts. Steady speeds of whole counts per sample, so the filtered speed settles exactly."""
    dt, n = 0.004, 400
    speed = steps * ENCODER_COUNT_RAD / dt               # rad/s, above the sign speeds
    limit = fraction * speed
    cal = C.neutral(baseline).with_(viscous_nm_s_per_rad=np.full(6, 0.004),
                                    friction_sign_nm=np.full((6, 2), 0.003),
                                    friction_speed_limit_rad_s=np.full(6, limit))

    def friction(c, per_sample):
        counts = np.zeros((n, 6))
        counts[:, joint] = np.arange(n) * per_sample
        terms, _ = CalibratedModel(baseline, c).joint_terms(counts, dt)
        spring = baseline.k[joint] * counts[-1, joint] * ENCODER_COUNT_RAD
        return terms.torque[-1, joint] - spring

    signs = 0.006 if limit > 0.02 else 0.003 + 0.003 * limit / 0.02
    at_limit = signs + 0.004 * limit
    assert friction(cal, steps) == pytest.approx(at_limit, rel=1e-9, abs=1e-15)
    assert friction(cal, 2 * steps) == pytest.approx(at_limit, rel=1e-9, abs=1e-15)
    free = cal.with_(friction_speed_limit_rad_s=np.zeros(6))
    assert friction(free, steps) == pytest.approx(0.006 + 0.004 * speed, rel=1e-9)
    above = cal.with_(friction_speed_limit_rad_s=np.full(6, 2 * speed))
    assert friction(above, steps) == pytest.approx(0.006 + 0.004 * speed, rel=1e-9)
    # Turning the other way, the friction turns sign; a limit below the sign speeds holds
    # the signs on their slopes too.
    assert friction(cal, -2 * steps) == pytest.approx(-at_limit, rel=1e-9, abs=1e-15)
    low = cal.with_(friction_speed_limit_rad_s=np.full(6, 0.003))
    held = 0.003 * 0.003 / 0.005 + 0.003 * 0.003 / 0.02 + 0.004 * 0.003
    assert friction(low, -steps) == pytest.approx(-held, rel=1e-9)


def test_a_led_speed_turns_before_the_filtered_one_at_a_reversal(baseline):
    """Why the lead: a joint decelerating through a reversal (counts on a parabola); the
    filtered speed changes sign after the true speed, the led one closer to it."""
    dt = 0.004
    t = np.arange(500) * dt
    true_speed = 2.0 - 8.0 * t                              # rad/s, turns at t = 0.25 s
    counts = np.round((2.0 * t - 4.0 * t ** 2) / ENCODER_COUNT_RAD)
    x = np.repeat(counts[:, None], 6, axis=1)
    turn = {}
    for lead in (0.0, C.DEFAULT_SPEED_LEAD_S):
        cal = C.neutral(baseline).with_(speed_lead_s=lead)
        terms, _ = CalibratedModel(baseline, cal).joint_terms(x, dt)
        turn[lead] = t[np.argmax(terms.speed[:, 0] < 0)]
    assert 0.25 < turn[C.DEFAULT_SPEED_LEAD_S] < turn[0.0]
    assert turn[0.0] - turn[C.DEFAULT_SPEED_LEAD_S] > 0.5 * C.DEFAULT_SPEED_LEAD_S
    assert np.argmax(true_speed < 0) * dt < turn[C.DEFAULT_SPEED_LEAD_S]
