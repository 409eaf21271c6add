"""The leftover verdict's held-out angle test: white noise of any level is not a function of a
joint's angle, a smooth function of the angle is, even far below the noise; and on a run
whose effect the vocabulary lacks, the leftover is placed on the joint whose encoder errs."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6 import twin
from delta6.diagnosis import leftover
from delta6.diagnosis.run import diagnose
from delta6.diagnosis.terms import TERMS
from delta6.link.logfile import LogData

N = 4000
#: The per-joint level of the angle test at the first step of Holm's step-down over the six
#: joints (the level a joint alone must reach).
LEVEL = leftover.ANGLE_ALPHA / 6


def _angle(seed: int, n: int = N) -> np.ndarray:
    """A joint angle wandering over its range, as under a random excitation: a few slow
    sinusoids of random frequency and phase (rad)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0
    freqs = rng.uniform(0.02, 0.3, 4)
    phases = rng.uniform(0, 2 * np.pi, 4)
    return 0.08 * np.sum(np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0) / 2


@given(st.floats(-50, 50))
def test_student_t_tail_matches_its_closed_forms(t):
    # One degree of freedom is Cauchy; two have a closed form of their own.
    assert leftover.student_t_sf(t, 1) == pytest.approx(0.5 - math.atan(t) / math.pi, abs=1e-12)
    assert leftover.student_t_sf(t, 2) == pytest.approx(
        0.5 * (1 - t / math.sqrt(2 + t * t)), abs=1e-12)
    for dof in (3, 8, 19, 40):
        assert leftover.student_t_sf(t, dof) + leftover.student_t_sf(-t, dof) \
            == pytest.approx(1.0, abs=1e-12)
        assert leftover.student_t_sf(t, dof) >= leftover.student_t_sf(t + 0.5, dof) - 1e-15
        assert 0.0 <= leftover.student_t_sf(t, dof) <= 1.0


def test_student_t_tail_matches_tabled_quantiles():
    for t, dof, p in ((2.093, 19, 0.025), (3.579, 19, 0.001), (2.015, 5, 0.05),
                      (4.781, 9, 0.0005)):
        assert leftover.student_t_sf(t, dof) == pytest.approx(p, rel=2e-3)


@settings(derandomize=True, max_examples=60)
@given(st.floats(1e-6, 1e3), st.integers(0, 2**31 - 1))
def test_white_noise_of_any_level_is_no_function_of_the_angle(level, seed):
    rng = np.random.default_rng(seed)
    angle = _angle(seed)
    tau = level * rng.standard_normal(N)
    result = leftover.angle_test(tau, angle)
    assert result["p"] > LEVEL
    # The test does not depend on the noise's level.
    again = leftover.angle_test(tau / level, angle)
    assert again["t"] == pytest.approx(result["t"], rel=1e-6, abs=1e-9)


def test_the_false_alarm_rate_on_white_noise_is_at_most_the_level():
    """The held-out gains' t test is calibrated (or conservative) on white noise: the share
    of 400 noise draws called structured at 5 % stays near or below 5 %."""
    rng = np.random.default_rng(7)
    ps = np.array([leftover.angle_test(rng.standard_normal(N), _angle(i))["p"]
                   for i in range(400)])
    assert np.mean(ps <= 0.05) <= 0.05 + 3 * math.sqrt(0.05 * 0.95 / 400)


@settings(derandomize=True, max_examples=60)
@given(st.floats(0.7, 3.0), st.floats(1e-5, 1e2), st.floats(0, 2 * np.pi),
       st.integers(0, 2**31 - 1))
def test_a_smooth_function_of_the_angle_is_found_below_the_noise(snr, level, phase, seed):
    """What is left of a periodic error over the shaft angle once its straight-line part is
    gone (a spring-rate term took it): found when its rms is 0.7 of the noise's, however
    unevenly the log's stretches sweep the angle."""
    rng = np.random.default_rng(seed)
    angle = _angle(seed)
    shaft = 8 * angle + phase            # a few radians of shaft turn over the joint's range
    error = np.sin(shaft) + 0.4 * np.sin(2 * shaft + 0.9)
    straight = np.polyval(np.polyfit(angle, error, 1), angle)
    curve = error - straight
    if curve.std() < 1e-9:
        return
    tau = level * (snr * curve / curve.std() + rng.standard_normal(N))
    result = leftover.angle_test(tau, angle)
    assert result["p"] <= LEVEL
    assert result["explained_var"] == pytest.approx((level * snr) ** 2, rel=0.5)


def test_a_stretch_beyond_the_others_angles_does_not_wipe_out_the_structure():
    """The last stretch sweeps angles no other stretch reaches: the polynomial fitted on the
    others, extrapolated there, would cost more than the structure gains elsewhere and the
    explained variance would come out 0 though the structure is plain."""
    rng = np.random.default_rng(5)
    n = 20 * 3000
    angle = 0.5 * np.sin(np.arange(n) / 40.0)
    angle[-3000:] = np.linspace(0.5, 1.2, 3000)
    tau = 0.5 * np.cos(2.5 * angle) + 0.2 * rng.standard_normal(n)
    result = leftover.angle_test(tau, angle)
    assert result["p"] <= LEVEL
    assert result["explained_var"] > 0.5 * np.var(0.5 * np.cos(2.5 * angle[:-3000]))


def _rows(amounts, structured, best, angle):
    return [({"joint": j + 1, "structured": s, "best": b, "angle_structured": a}, x)
            for j, (x, s, b, a) in enumerate(zip(amounts, structured, best, angle))]


def test_a_joint_structured_in_time_only_does_not_carry_an_angle_structure():
    """A joint above the noise floor whose leftover no shape explains (the ladder's parameters
    changing from one held-out fold to the next) is not where an angle error lives."""
    even = "even polynomial"
    rows = _rows([4.0, 0.1, 0.1, 0.1, 0.5, 0.1], [True] + [False] * 5,
                 [None, None, None, None, even, None], [False] * 4 + [True, False])
    assert leftover._carrying(rows) == [5]
    # Without any angle structure, the joints above the floor, as before.
    rows = _rows([4.0, 0.1, 0.1, 0.1, 0.5, 0.1], [True] + [False] * 5,
                 [None, None, None, None, even, None], [False] * 6)
    assert leftover._carrying(rows) == [1]


def test_an_encoder_error_the_vocabulary_lacks_is_placed_on_its_joint(baseline):
    """Magnet eccentricity on joint 5, with the families added for it withheld: a spring-rate
    term takes its straight-line part; what is left is below the noise floor on every axis,
    yet a function of joint 5's angle."""
    effect = twin.make_effect("encoder_periodic_error", seed=3, formulation="eccentricity",
                              magnitude=0.9, joints=[5])
    newest = ("nonlinear_spring", "encoder_periodic_error", "harness")
    terms = [t for t in TERMS if t.name not in newest]
    r = twin.simulate(baseline, [effect], duration_s=240.0, rate_hz=50.0, seed=3,
                      record_temp=True)
    log = LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c)
    left = diagnose(log, baseline, seed=0, terms=terms)["unexplained"]["verdict"]
    assert left["structured"] and left["joints"] == [5]
    assert left["shape"] in ("odd polynomial", "even polynomial", "periodic in the angle")
    assert left["per_joint"][4]["angle_structured"]
    assert not any(row["angle_structured"] for row in left["per_joint"][:4])


@settings(max_examples=300)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=8), st.floats(1e-4, 0.2))
def test_holm_rejects_what_bonferroni_does_and_a_prefix_of_the_sorted_p_values(p, alpha):
    reject = leftover.holm(p, alpha)
    bonferroni = [x <= alpha / len(p) for x in p]
    assert all(r or not b for r, b in zip(reject, bonferroni))
    rejected = sorted(x for x, r in zip(p, reject) if r)
    kept = [x for x, r in zip(p, reject) if not r]
    assert not kept or not rejected or max(rejected) <= min(kept)
    for rank, x in enumerate(rejected):                 # each at its step's level
        assert x <= alpha / (len(p) - rank)


def test_holm_finds_a_second_joint_bonferroni_misses_and_keeps_the_false_alarm_rate():
    alpha = leftover.ANGLE_ALPHA
    # One joint clearly structured, a second just above the Bonferroni level: Holm judges the
    # second at alpha / 5.
    p = [1.7e-4, 0.4, 0.9, 0.3, 0.6, 1e-9]
    assert leftover.holm(p, alpha) == [True, False, False, False, False, True]
    assert 1.7e-4 > alpha / 6
    # Six independent null p-values: at least one rejected in about alpha of the draws.
    rng = np.random.default_rng(0)
    draws = rng.random((20_000, 6))
    alarms = np.mean([any(leftover.holm(list(row), 0.05)) for row in draws])
    assert alarms <= 0.05 * 1.15
