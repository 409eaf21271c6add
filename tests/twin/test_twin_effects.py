"""The effect vocabulary: parameters, ranges, formulations, overrides, truth records."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6 import twin
from delta6.twin.effects import Stage

from conftest import ROOT
from support.twinkit import CLEAN, residual

HISTORY = ("spring_hysteresis", "joint_friction", "backlash")


def test_the_effect_vocabulary_is_the_documented_one():
    assert twin.EFFECT_NAMES == ("encoder_offset", "stiffness_mismatch", "geometry_error",
                                 "spring_hysteresis", "joint_friction", "backlash",
                                 "link_compliance", "sensor_latency", "thermal_drift",
                                 "nonlinear_spring", "encoder_periodic_error", "harness")


@pytest.mark.parametrize("name", twin.EFFECT_NAMES)
def test_every_effect_declares_where_it_acts_and_its_parameters(name):
    cls = twin.REGISTRY[name]
    assert cls.NAME == name
    assert cls.ACTS_ON and all(isinstance(s, Stage) for s in cls.ACTS_ON)
    assert cls.FORMULATIONS and len(set(cls.FORMULATIONS)) == len(cls.FORMULATIONS)
    if name in HISTORY:
        assert len(cls.FORMULATIONS) >= 2
    assert any(s.primary for s in cls.SPECS)
    for s in cls.SPECS:
        assert s.unit and s.doc and 0 < s.low <= s.high
        assert s.valid[0] <= min(s.low, -s.high if s.sign != "+" else s.low)
        assert s.formulations is None or set(s.formulations) <= set(cls.FORMULATIONS)


def test_docs_describe_every_effect_and_formulation():
    text = (ROOT / "docs" / "twin.md").read_text()
    for name, cls in twin.REGISTRY.items():
        assert f"### `{name}`" in text
        for f in cls.FORMULATIONS:
            assert f"`{f}`" in text, (name, f)
        for s in cls.SPECS:
            assert f"`{s.name}`" in text, (name, s.name)


@given(st.sampled_from(twin.EFFECT_NAMES), st.floats(0, 1), st.integers(0, 2**31))
def test_drawn_parameters_stay_in_their_realistic_ranges(name, magnitude, seed):
    cls = twin.REGISTRY[name]
    for formulation in cls.FORMULATIONS:
        e = twin.make_effect(name, seed, formulation=formulation, magnitude=magnitude)
        for s in cls.specs_for(formulation):
            v = np.abs(e.p(s.name))
            assert np.all((v >= s.low * (1 - 1e-12)) & (v <= s.high * (1 + 1e-12))), s.name
            signs = np.sign(e.p(s.name))
            if s.sign == "+":
                assert np.all(signs > 0)
            elif s.sign == "-":
                assert np.all(signs < 0)


@pytest.mark.parametrize("name", twin.EFFECT_NAMES)
def test_magnitude_moves_the_strength_across_the_range(name):
    cls = twin.REGISTRY[name]
    spec = next(s for s in cls.SPECS if s.primary)
    if spec.low == spec.high:
        pytest.skip("fixed parameter")
    weak = np.abs(twin.make_effect(name, 3, magnitude=0.0).p(spec.name))
    strong = np.abs(twin.make_effect(name, 3, magnitude=1.0).p(spec.name))
    assert weak.max() < spec.low * math.exp(0.25) * 1.0001
    assert strong.min() > spec.high * math.exp(-0.25) * 0.9999


def test_overrides_broadcast_and_are_validated():
    e = twin.make_effect("joint_friction", 1, formulation="lugre", coulomb_nm=0.01)
    assert np.array_equal(e.p("coulomb_nm"), np.full(6, 0.01))
    e = twin.make_effect("stiffness_mismatch", 1, deviation=[0.1, 0, 0, 0, 0, -0.1])
    assert e.p("deviation")[0] == 0.1 and e.p("deviation")[5] == -0.1
    for bad, message in [
        (dict(deviation=[0.1, 0.2]), "one number or 6 values"),
        (dict(deviation=0.9), "must lie in"),
        (dict(deviation=float("nan")), "finite"),
        (dict(ratio=1.1), "unknown parameter 'ratio'"),
        (dict(formulation="quadratic"), "unknown formulation"),
        (dict(magnitude=1.5), "magnitude must lie in"),
        (dict(joints=7), "joints must be numbers 1..6"),
    ]:
        with pytest.raises(twin.EffectError, match=message):
            twin.make_effect("stiffness_mismatch", 1, **bad)
    with pytest.raises(twin.EffectError, match="takes no joints"):
        twin.make_effect("geometry_error", 1, joints=[1])
    with pytest.raises(twin.EffectError, match="unknown effect 'gravity'"):
        twin.make_effect("gravity", 1)


def test_joints_restrict_an_effect_and_overrides_do_not_change_other_draws():
    e = twin.make_effect("backlash", 4, joints=[2, 5])
    assert np.count_nonzero(e.p("play_rad")) == 2 and e.p("play_rad")[1] > 0
    plain = twin.make_effect("joint_friction", 4, formulation="stribeck")
    pinned = twin.make_effect("joint_friction", 4, formulation="stribeck", coulomb_nm=0.005)
    for key in ("viscous_nm_s_per_rad", "static_ratio", "stribeck_rad_s"):
        assert np.array_equal(plain.p(key), pinned.p(key))


@pytest.mark.parametrize("name", twin.EFFECT_NAMES)
def test_truth_records_rebuild_the_same_effect_and_summaries_share_keys(name):
    cls = twin.REGISTRY[name]
    keys = None
    for formulation in cls.FORMULATIONS:
        e = twin.make_effect(name, 9, formulation=formulation, magnitude=0.3)
        record = e.to_truth()
        again = cls.from_truth(record)
        assert again.formulation == formulation
        for k, v in e.params.items():
            assert np.array_equal(again.p(k), v)
        assert set(record["units"]) == set(record["parameters"])
        if keys is None:
            keys = set(record["summary"])
        assert set(record["summary"]) == keys, "summary must not depend on the formulation"


def test_summaries_measure_what_they_say():
    h = twin.make_effect("spring_hysteresis", 2, formulation="bouc_wen", half_width_nm=0.01,
                         reversal_angle_rad=0.02).summary()
    assert np.allclose(h["half_width_nm"], 0.01)
    assert np.allclose(h["reversal_angle_90_rad"], 0.02 * math.log(10), atol=5e-4)
    p = twin.make_effect("spring_hysteresis", 2, formulation="play_sum",
                         saturation_angle_rad=0.06).summary()
    # equal weights on radii r_i = i/6 * 0.06: 90 % of the swing after 2 * 0.0... of travel
    assert np.all(p["reversal_angle_90_rad"] < 2 * 0.06)
    f = twin.make_effect("joint_friction", 2, formulation="coulomb_viscous", coulomb_nm=0.004,
                         viscous_nm_s_per_rad=0.002, smoothing_rad_s=0.002).summary()
    assert np.allclose(f["coulomb_equiv_nm"], 0.004, rtol=1e-6)
    assert np.allclose(f["viscous_equiv_nm_s_per_rad"], 0.002, rtol=1e-5)
    assert np.allclose(f["torque_at_ref_speed_nm"], 0.004 + 0.1 * 0.002, rtol=1e-6)
    b = twin.make_effect("backlash", 2, formulation="dead_zone", play_rad=0.006).summary()
    assert np.allclose(b["dwell_rad"], 0.006) and np.allclose(b["play_rad"], 0.006)
    s = twin.make_effect("backlash", 2, formulation="elastic_contact", play_rad=0.006,
                         softness=0.5).summary()
    assert np.allclose(s["dwell_rad"], 0.003)


def test_every_pair_of_effects_composes(baseline):
    effects = {n: twin.make_effect(n, 5, magnitude=0.7) for n in twin.EFFECT_NAMES}
    floor = twin.simulate(baseline, [], duration_s=8, seed=5, measurement=CLEAN)
    for a, b in itertools.combinations(twin.EFFECT_NAMES, 2):
        r = twin.simulate(baseline, [effects[a], effects[b]], duration_s=8, seed=5,
                          measurement=CLEAN)
        assert np.all(np.isfinite(r.wrench)) and np.all(np.isfinite(r.theta))
        assert np.abs(residual(r)).max() > np.abs(residual(floor)).max() + 1e-4, (a, b)
    everything = twin.simulate(baseline, list(effects.values()), duration_s=8, seed=5)
    assert np.all(np.isfinite(everything.wrench))


@pytest.mark.parametrize("name", twin.EFFECT_NAMES)
def test_each_effect_alone_opens_a_gap_and_leaves_the_rest_alone(baseline, name):
    ideal = twin.simulate(baseline, [], duration_s=20, seed=2, measurement=CLEAN)
    r = twin.simulate(baseline, [twin.make_effect(name, 2, magnitude=1.0)], duration_s=20,
                      seed=2, measurement=CLEAN)
    assert np.array_equal(r.true_angles, ideal.true_angles)    # the robot's path is the same
    gap = np.abs(residual(r)).max(axis=0)
    assert gap.max() > 1e-3
    stages = twin.REGISTRY[name].ACTS_ON
    if Stage.ANGLE not in stages:
        assert np.array_equal(r.theta, ideal.theta)
    if stages == (Stage.ANGLE,):
        assert np.array_equal(r.wrench, ideal.wrench)


@given(st.text(max_size=60))
def test_effect_request_parser_fails_only_with_a_clear_error(text):
    try:
        request = twin.parse_request(text)
    except twin.EffectError as exc:
        assert str(exc) and "\n" not in str(exc)
    else:
        assert request.name in twin.EFFECT_NAMES


@given(st.sampled_from(twin.EFFECT_NAMES), st.data())
def test_effect_requests_round_trip(name, data):
    cls = twin.REGISTRY[name]
    formulation = data.draw(st.sampled_from(cls.FORMULATIONS))
    spec = data.draw(st.sampled_from(cls.specs_for(formulation)))
    count = int(np.prod(spec.dims)) if spec.dims else 1
    values = data.draw(st.lists(st.floats(spec.low, spec.high), min_size=count, max_size=count))
    magnitude = data.draw(st.floats(0, 1))
    text = (f"{name}:formulation={formulation},magnitude={magnitude!r},"
            f"{spec.name}={'/'.join(repr(v) for v in values)}")
    request = twin.parse_request(text)
    assert (request.formulation, request.magnitude) == (formulation, magnitude)
    effect = twin.build_effects([request], 1)[0]
    expected = np.asarray(values if count > 1 else values[0])
    assert np.array_equal(effect.p(spec.name), np.broadcast_to(expected, spec.dims))
