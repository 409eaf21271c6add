"""The effects real magnetic-encoder sensors add to the first vocabulary: a nonlinear spring,
the encoder's periodic error over its shaft angle, a harness pulling on the plate."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6 import twin
from delta6.core import model
from delta6.twin.effects.encoder_periodic_error import EncoderPeriodicError
from delta6.twin.effects.harness import REF_DISPLACEMENT_M
from delta6.twin.effects.nonlinear_spring import REF_ANGLE_RAD

from support.twinkit import CLEAN, residual, sine_path

angles = st.floats(-0.6, 0.6)


@pytest.mark.parametrize("formulation", ["cubic", "progressive"])
@given(q=angles)
def test_nonlinear_spring_is_odd_and_states_its_size_at_the_reference(formulation, q):
    e = twin.make_effect("nonlinear_spring", 5, formulation=formulation, magnitude=0.7)
    k = np.full(6, 0.3)
    qs = np.full((1, 6), q)
    assert np.allclose(e.extra_torque_at(qs, k), -e.extra_torque_at(-qs, k), atol=1e-15)
    at_ref = e.extra_torque_at(np.full((1, 6), REF_ANGLE_RAD), k)[0]
    assert np.allclose(at_ref, k * REF_ANGLE_RAD * e.summary()["stiffening"])
    assert np.all(e.extra_torque_at(np.zeros((1, 6)), k) == 0)


@pytest.mark.parametrize("formulation", ["eccentricity", "harmonics"])
@given(q=angles)
def test_encoder_error_is_zero_at_rest_and_periodic_over_a_turn(formulation, q):
    e = twin.make_effect("encoder_periodic_error", 6, formulation=formulation, magnitude=0.8)
    assert isinstance(e, EncoderPeriodicError)
    qs = np.full((1, 6), q)
    assert np.allclose(e.error(np.zeros((1, 6))), 0.0, atol=1e-15)
    assert np.allclose(e.error(qs), e.error(qs + 2 * np.pi), atol=1e-12)
    assert np.all(np.abs(e.error(qs)) <= 2.5 * e.p("amplitude_rad") + 1e-15)


def test_encoder_error_shows_as_an_angle_error_that_depends_on_the_angle(baseline):
    effect = twin.make_effect("encoder_periodic_error", 7, formulation="harmonics",
                              magnitude=1.0, joints=[4])
    r = twin.simulate(baseline, [effect], duration_s=20, seed=2, measurement=CLEAN,
                      path=sine_path(4, 0.4, 0.1))
    err = r.theta - r.true_angles
    assert np.allclose(err[:, [0, 1, 2, 4, 5]], 0.0)
    assert np.allclose(err[:, 3], effect.error(r.true_angles)[:, 3], atol=1e-12)
    assert np.ptp(err[:, 3]) > 1e-3


@pytest.mark.parametrize("formulation", ["linear", "cable"])
def test_harness_pulls_on_the_plate_by_where_it_is(baseline, formulation):
    e = twin.make_effect("harness", 8, formulation=formulation, magnitude=0.8)
    u = e.p("direction") / np.linalg.norm(e.p("direction"))
    force = e.force(REF_DISPLACEMENT_M * u)
    assert np.linalg.norm(force) == pytest.approx(e.summary()["force_at_ref_n"])
    assert force @ u < 0                      # it pulls the plate back
    # Its joint torques are the virtual work of the force: a small joint motion dq moves the
    # clamp by J dq, and tau . dq = f . (J dq).
    sig = twin.effects.Signals(t=np.zeros(1), q=np.full((1, 6), 0.1), qd=np.zeros((1, 6)),
                               temp_c=np.full(1, 23.0),
                               nominal=model.Params.from_design(baseline))
    tau = e.extra_torque(sig)[0]
    dq = np.array([1e-5, -2e-5, 1e-5, 2e-5, 1e-5, -1e-5])
    here = e._clamp(sig.nominal, sig.q)
    moved = e._clamp(sig.nominal, sig.q + dq)
    f = e.force(here - e._clamp(sig.nominal, np.zeros(6)))
    assert tau @ dq == pytest.approx(float(f[0] @ (moved - here)[0]), rel=1e-3)


def test_harness_opens_a_gap_that_grows_with_its_stiffness(baseline):
    gaps = []
    for m in (0.1, 0.9):
        e = twin.make_effect("harness", 9, formulation="linear", magnitude=m)
        r = twin.simulate(baseline, [e], duration_s=60, seed=3, measurement=CLEAN)
        gaps.append(np.abs(residual(r)[:, :3]).max())
    assert gaps[1] > 2 * gaps[0] > 0
