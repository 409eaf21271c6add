"""Fitting calibrations to twin runs: parameters recovered, held-out error shrinks on a run the
fit never saw, and clean data gets an empty calibration."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6 import twin
from delta6.calibration import calibrate
from delta6.calibration.fit import check_effects
from delta6.core import calibration as C
from delta6.core.calibrated import CalibratedModel, counts_from_angles, periods_between, sample_period
from delta6.core.errors import UserError
from delta6.core.spec import full_scale


@pytest.fixture(scope="module")
def unit(baseline):
    effects = [twin.make_effect("stiffness_mismatch", 4, magnitude=0.9),
               twin.make_effect("encoder_offset", 4, magnitude=0.8),
               twin.make_effect("joint_friction", 4, magnitude=0.8)]
    fit_run = twin.simulate(baseline, effects, duration_s=120, rate_hz=50, seed=4)
    truth = fit_run.truth
    check_run = twin.simulate(duration_s=60, rate_hz=50, **twin.same_unit(truth, 5))
    return effects, fit_run, check_run


def test_named_effects_are_recovered_and_the_unseen_run_shrinks(baseline, unit):
    effects, fit_run, check_run = unit
    fit = calibrate(fit_run, baseline, effects=["stiffness_mismatch", "encoder_offset",
                                                "joint_friction"])
    cal = fit.calibration
    truth = {e.NAME: e.params for e in effects}
    np.testing.assert_allclose(cal.rate_ratio, 1 + truth["stiffness_mismatch"]["deviation"],
                               atol=0.004)
    np.testing.assert_allclose(cal.offset_rad, truth["encoder_offset"]["offset_rad"],
                               atol=4e-4)
    # The rig has no delay: its latency, always fitted, stays under a millisecond (the
    # paper rig's 10 ms would show).
    assert fit.chosen_by == "--effect" and 0.0 <= fit.latency_s < 1e-3
    assert np.all(np.array(fit.heldout_after["p99_pct"])
                  < 0.4 * np.array(fit.heldout_before["p99_pct"]))
    fs = full_scale(baseline)
    before = np.percentile(np.abs(check_run.model_wrench() - check_run.wrench) / fs, 99, 0)
    after = np.percentile(np.abs(CalibratedModel(baseline, cal).predict(check_run)
                                 - check_run.wrench) / fs, 99, 0)
    assert np.all(after < 0.4 * before), (before, after)


def test_the_diagnosis_picks_the_effects(baseline, unit):
    _, fit_run, _ = unit
    fit = calibrate(fit_run, baseline)
    assert fit.chosen_by == "diagnosis"
    assert {"stiffness_mismatch", "encoder_offset"} <= set(fit.calibration.effects)
    assert "stiffness_mismatch" in fit.diagnosis["present"]


def test_clean_data_gets_an_empty_calibration(baseline):
    run = twin.simulate(baseline, [], duration_s=120, rate_hz=50, seed=6)
    fit = calibrate(run, baseline)
    assert fit.calibration.effects == ()
    np.testing.assert_allclose(CalibratedModel(baseline, fit.calibration).predict(run),
                               run.model_wrench(), atol=1e-9)


def test_latency_is_fitted_as_the_rigs_and_not_applied(baseline):
    effect = twin.make_effect("sensor_latency", 1, latency_s=0.03)
    run = twin.simulate(baseline, [effect], duration_s=120, rate_hz=50, seed=7)
    fit = calibrate(run, baseline, effects=["sensor_latency"])
    assert fit.latency_s == pytest.approx(0.03, rel=0.15)
    assert fit.calibration.effects == ()
    assert fit.calibration.fit["rig_latency_s"] == pytest.approx(fit.latency_s)


K_NM_PER_RAD = 0.639236          # the baseline design's spring rate
TRUE_VISCOUS = 0.002             # N*m*s/rad, the paper unit's


@pytest.fixture(scope="module")
def late_rig(baseline):
    """A unit with Coulomb and viscous friction on a rig whose reference is 10 ms late (the
    paper rig's), and the same unit on a rig without delay."""
    friction = twin.make_effect("joint_friction", 1, formulation="coulomb_viscous",
                                coulomb_nm=0.002, viscous_nm_s_per_rad=TRUE_VISCOUS,
                                smoothing_rad_s=0.005)
    late = twin.simulate(baseline, [friction, twin.make_effect("sensor_latency", 1,
                                                                latency_s=0.01)],
                         duration_s=240, rate_hz=50, seed=3)
    prompt = twin.simulate(**twin.without(late.truth, ["sensor_latency"]))
    return late, prompt


# A late reference (L k w at the spring) and a viscous friction (b w) nearly share their
# signature: the log pins them along L k + b far better than apart. The fit must put the delay
# in the rig, not in a negative friction; along the trade it is held to a quarter of the 10 ms
# (an eighth of the 20 ms sample), the viscous coefficient to the same trade, 2.5 ms x k.
TRADE_S = 0.0025


@pytest.fixture(scope="module")
def late_fit(baseline, late_rig):
    return calibrate(late_rig[0], baseline, effects=["joint_friction"])


def test_a_late_rig_is_fitted_as_the_rigs_latency_not_as_negative_friction(late_fit):
    fit = late_fit
    viscous = fit.calibration.viscous_nm_s_per_rad
    assert np.all(viscous >= 0.0)
    np.testing.assert_allclose(viscous, TRUE_VISCOUS, atol=TRADE_S * K_NM_PER_RAD)
    assert fit.latency_s == pytest.approx(0.01, abs=TRADE_S)
    assert fit.calibration.fit["rig_latency"] == "fitted"
    # The calibrated wrench is not late: the held-out Table V against the reference advanced
    # by the fitted latency is the calibration's own, better than against the late one and
    # better than the analytical model's against the same reference.
    before, after = fit.heldout_before_rig["p99_pct"], fit.heldout_after_rig["p99_pct"]
    assert np.all(np.array(after) < np.array(before))
    assert np.mean(after) < np.mean(fit.heldout_after["p99_pct"])
    assert fit.calibration.fit["heldout_after_rig"] == fit.heldout_after_rig


def test_a_rig_without_delay_fits_no_latency_and_the_true_friction(baseline, late_rig):
    _, prompt = late_rig
    fit = calibrate(prompt, baseline, effects=["joint_friction"])
    assert 0.0 <= fit.latency_s < 1e-3
    np.testing.assert_allclose(fit.calibration.viscous_nm_s_per_rad, TRUE_VISCOUS,
                               atol=1e-3 * K_NM_PER_RAD)


def test_a_stated_rig_latency_is_used_not_fitted(baseline, late_rig):
    late, _ = late_rig
    fit = calibrate(late, baseline, effects=["joint_friction"], rig_latency_s=0.01)
    assert fit.latency_s == 0.01 and fit.latency_given
    assert fit.calibration.fit["rig_latency"] == "given"
    np.testing.assert_allclose(fit.calibration.viscous_nm_s_per_rad, TRUE_VISCOUS,
                               atol=1e-3 * K_NM_PER_RAD)
    with pytest.raises(UserError, match="0..0.2 s"):
        calibrate(late, baseline, effects=["joint_friction"], rig_latency_s=-0.01)
    with pytest.raises(UserError, match="drop --effect sensor_latency"):
        calibrate(late, baseline, effects=["sensor_latency"], rig_latency_s=0.01)


def test_fitted_friction_opposes_the_motion_at_every_speed(late_fit, late_rig):
    """On the late rig a free fit wrote a negative viscous friction; bounded, the friction
    torque the board adds is >= 0 at every positive speed up to the log's fastest joint."""
    cal = late_fit.calibration
    speeds = np.asarray(cal.friction_speeds_rad_s)
    fastest = np.abs(np.gradient(late_rig[0].theta, late_rig[0].t, axis=0)).max()
    w = np.linspace(0.0, max(fastest, 3.0 * speeds.max()), 2000)
    torque = (cal.friction_sign_nm[:, None, :]
              * np.clip(w[None, :, None] / speeds[None, None, :], -1, 1)).sum(axis=-1) \
        + cal.viscous_nm_s_per_rad[:, None] * w[None, :]
    assert np.all(torque >= -1e-12)


def test_the_friction_is_held_beyond_the_fastest_speed_its_log_reached(baseline, late_fit,
                                                                     late_rig, unit):
    """A fitted friction is known up to the board's fastest joint speed on its log: the
    calibration holds it there (a slope fitted on slow motion is not extrapolated); a
    calibration without a friction sets no limit (its hash stays what it was)."""
    log = late_rig[0]
    model = CalibratedModel(baseline, C.new_settings(baseline))
    dt = sample_period(log.t)
    terms, _ = model.joint_terms(counts_from_angles(log.theta), dt,
                                 periods=periods_between(log.t, dt))
    np.testing.assert_allclose(late_fit.calibration.friction_speed_limit_rad_s,
                               np.abs(terms.speed).max(axis=0), rtol=1e-12)
    fit = calibrate(unit[1], baseline, effects=["stiffness_mismatch", "encoder_offset"])
    assert not np.any(fit.calibration.friction_speed_limit_rad_s)
    assert "friction_speed_limit_rad_s" not in fit.calibration.canonical()
    assert "speed_lead_s" not in fit.calibration.canonical()
    assert late_fit.calibration.speed_lead_s == C.DEFAULT_SPEED_LEAD_S


def test_the_held_out_table_holds_the_friction_at_the_training_blocks_speeds(
        baseline, monkeypatch):
    """The file's held-out table is what the board would give on blocks the fit never saw:
    its calibration holds the friction at the fastest speed of the training blocks (not of
    the whole log, which includes the held-out ones); the file's, at the whole log's. On
    this run four joints go fastest in the held-out blocks (joint 6 twice as fast)."""
    from delta6.calibration import fit as fit_module
    limits = []
    original = fit_module.with_speed_limit

    def recording(cal, reached):
        limits.append(np.asarray(reached))
        return original(cal, reached)

    monkeypatch.setattr(fit_module, "with_speed_limit", recording)
    friction = twin.make_effect("joint_friction", 1, formulation="coulomb_viscous",
                                coulomb_nm=0.002, viscous_nm_s_per_rad=TRUE_VISCOUS,
                                smoothing_rad_s=0.005)
    log = twin.simulate(baseline, [friction], duration_s=120, rate_hz=50, seed=4)
    fit = calibrate(log, baseline, effects=["joint_friction"])
    dt = sample_period(log.t)
    terms, _ = CalibratedModel(baseline, C.new_settings(baseline)).joint_terms(
        counts_from_angles(log.theta), dt, periods=periods_between(log.t, dt))
    speed = np.abs(terms.speed)
    bounds = np.linspace(0, len(log.t), fit_module.N_BLOCKS + 1).astype(int)
    _, train = fit_module.heldout_split()
    rows = np.concatenate([np.arange(bounds[b], bounds[b + 1]) for b in train])
    assert np.sum(speed.max(axis=0) > 1.05 * speed[rows].max(axis=0)) >= 3
    np.testing.assert_allclose(limits[0], speed[rows].max(axis=0), rtol=1e-12)
    np.testing.assert_allclose(limits[-1], speed.max(axis=0), rtol=1e-12)
    np.testing.assert_allclose(fit.calibration.friction_speed_limit_rad_s, limits[-1])


@pytest.mark.parametrize("bad", [["thermal_drift"], ["warp_drive"], ["harness"],
                                 ])
def test_uncorrectable_or_unknown_effects_are_refused(bad):
    with pytest.raises(UserError) as err:
        check_effects(bad)
    assert bad[0] in str(err.value)


def test_every_family_the_diagnosis_names_is_corrected_or_says_why_not():
    """A named effect the device does not correct must leave a line in the file's
    ``fit.not_applied``, never vanish."""
    from delta6.core.calibration import CORRECTED, NOT_APPLIED
    from delta6.diagnosis.terms import TERMS
    names = {t.name for t in TERMS}
    assert names <= set(CORRECTED) | set(NOT_APPLIED), names - set(CORRECTED) - set(NOT_APPLIED)
    assert not set(CORRECTED) & set(NOT_APPLIED)


def test_a_log_longer_than_one_streamed_piece_is_calibrated(baseline):
    """The diagnosis streams long logs in pieces; the calibration's columns come from the
    calibrated model run over the whole log, so they must see that log in one piece."""
    from delta6.diagnosis.stream import PIECE_SAMPLES
    effects = [twin.make_effect("stiffness_mismatch", 8, magnitude=0.9),
               twin.make_effect("joint_friction", 8, magnitude=0.8)]
    run = twin.simulate(baseline, effects, duration_s=1.2 * PIECE_SAMPLES / 50, rate_hz=50,
                        seed=8)
    assert len(run.t) > PIECE_SAMPLES
    fit = calibrate(run, baseline, effects=["stiffness_mismatch", "joint_friction"])
    np.testing.assert_allclose(fit.calibration.rate_ratio,
                               1 + effects[0].params["deviation"], atol=0.004)


@pytest.fixture(scope="module")
def paper_run(baseline):
    """A short run of the twin's flagship unit: every correctable effect at once, a geometry
    the history effects can masquerade as."""
    return twin.simulate(baseline, twin.scenario_effects("paper", 1), duration_s=120,
                         rate_hz=50, seed=1)


def _plausible_and_saved(fit, tmp_path):
    """Every fitted family within the diagnosis's plausible limits, and the file writes and
    reads back (its validation holds)."""
    from delta6.calibration.families import families
    from delta6.core import calibration as calibration_file
    cal = fit.calibration
    for effect in cal.effects:
        family = families(cal)[effect]
        assert not family.implausible(cal), (effect, family.plausibility(cal))
    path = calibration_file.save(cal, tmp_path / "unit.toml")
    assert calibration_file.load(path).hash32() == cal.hash32()


def test_the_paper_unit_is_calibrated_with_plausible_parameters(baseline, paper_run, tmp_path):
    """Unbounded, the Gauss-Newton fit drove a + b of a branch (which the statics hardly see)
    further with every iteration, past the file's 5 mm bound; the priors hold it."""
    fit = calibrate(paper_run, baseline, effects=[
        "stiffness_mismatch", "joint_friction", "link_compliance", "encoder_offset",
        "spring_hysteresis", "backlash", "geometry_error"])
    assert "geometry_error" in fit.calibration.effects
    assert fit.calibration.fit["left_out"] == []
    _plausible_and_saved(fit, tmp_path)
    assert np.all(np.abs(fit.calibration.delta_a_mm + fit.calibration.delta_b_mm) < 0.5)
    assert np.all(np.array(fit.heldout_after["p99_pct"])
                  < 0.35 * np.array(fit.heldout_before["p99_pct"]))


def test_a_family_that_fits_only_implausibly_is_left_out_with_a_note(baseline, paper_run,
                                                                     tmp_path):
    """Without the history families, the geometry soaks up their direction-dependent torques
    with millimetres of error: it is left out, said, and the rest is still calibrated."""
    fit = calibrate(paper_run, baseline, effects=["stiffness_mismatch", "link_compliance",
                                                  "encoder_offset", "geometry_error"])
    cal = fit.calibration
    assert "geometry_error" not in cal.effects and cal.fit["left_out"] == ["geometry_error"]
    assert any(n.startswith("geometry_error: left out") for n in fit.notes)
    assert not np.any(cal.delta_a_mm) and not np.any(cal.gimbal_misalignment_rad)
    assert {"stiffness_mismatch", "encoder_offset"} <= set(cal.effects)
    _plausible_and_saved(fit, tmp_path)
    assert np.all(np.array(fit.heldout_after["p99_pct"])
                  < 0.8 * np.array(fit.heldout_before["p99_pct"]))


def test_every_family_carries_the_diagnosis_priors_and_limits(baseline):
    from delta6.calibration.families import families
    from delta6.core.calibration import neutral
    from delta6.diagnosis.terms import TERMS
    cal = neutral(baseline)
    by_name = {t.name: t for t in TERMS}
    for name, family in families(cal).items():
        term = by_name[name]
        assert family.term_map.shape == (len(term.param_names), len(family.param_names))
        assert len(family.prior_sd) == len(family.param_names)
        assert set(family.prior_sd) <= set(term.prior_sd)
        assert len(family.values(cal)) == len(family.param_names)
        assert not np.any(family.values(cal)) and not family.implausible(cal)
    # the play radii of 16, 64, 256 counts are the diagnosis's 0.006, 0.024, 0.096 rad
    hyst = families(cal)["spring_hysteresis"].term_map[:5, :3]
    assert np.argmax(hyst, axis=0).tolist() == [0, 2, 4]
    big = cal.with_(backlash_play_rad=np.full(6, 0.06))
    assert families(big)["backlash"].implausible(big)


def test_each_parameter_is_checked_against_its_own_limit(baseline):
    """Two hysteresis weights of one joint, far out of bounds with opposite signs, summed to
    zero in the term's coefficients and passed; each on its own is implausible."""
    from delta6.calibration.families import families
    from delta6.core.calibration import neutral
    cal = neutral(baseline)
    weights = np.zeros((6, len(cal.hysteresis_radii_counts)))
    weights[2, :2] = [0.3, -0.3]
    cal = cal.with_(hysteresis_nm=weights)
    family = families(cal)["spring_hysteresis"]
    failed = family.implausible(cal)
    assert [c["quantity"] for c in failed] == ["loop_half_width_nm"]
    assert failed[0]["largest"] == pytest.approx(0.3)
    # Within the limit each, they stay plausible.
    fine = cal.with_(hysteresis_nm=weights / 10)
    assert not family.implausible(fine)


@settings(max_examples=40, deadline=None)
@given(radii=st.lists(st.integers(1, 4096), min_size=1, max_size=4, unique=True),
       speeds=st.lists(st.floats(1e-4, 10.0), min_size=1, max_size=4))
def test_any_settings_map_each_parameter_onto_one_diagnosis_coefficient(baseline, radii,
                                                                         speeds):
    """Whatever the play radii and sign speeds, each calibration parameter maps onto exactly
    one coefficient of the diagnosis's term, and so takes a prior scale and a limit."""
    from delta6.calibration.families import families
    from delta6.core.calibration import neutral
    cal = neutral(baseline).with_(
        hysteresis_radii_counts=tuple(radii), hysteresis_nm=np.zeros((6, len(radii))),
        friction_speeds_rad_s=tuple(speeds), friction_sign_nm=np.zeros((6, len(speeds))))
    for family in families(cal).values():
        m = family.term_map
        assert m.shape[1] == len(family.param_names) == len(family.values(cal))
        assert np.all((m == 0) | (m == 1)) and np.all(m.sum(axis=0) == 1)
        assert len(family.prior_sd) == m.shape[1] and min(family.prior_sd) > 0


def test_effects_named_in_a_wider_statement_are_fitted_where_they_were_named():
    from delta6.calibration.fit import effects_to_fit
    diagnosis = {"present": ["stiffness_mismatch", "joint_friction", "link_compliance"],
                 "groups": [{"members": ["joint_friction", "backlash", "spring_hysteresis"],
                             "named_alone": ["joint_friction"], "folded": ["backlash"]}]}
    assert effects_to_fit(diagnosis) == ["stiffness_mismatch", "joint_friction", "backlash",
                                         "link_compliance"]
    # A group verdict from the backward test (nothing folded) adds nothing.
    diagnosis["groups"][0].pop("folded")
    assert effects_to_fit(diagnosis) == diagnosis["present"]
    # A stiffening spring's straight part is a rate error the board corrects.
    spring = {"present": ["nonlinear_spring", "encoder_offset"], "groups": [],
              "straight_part": [{"name": "stiffness_mismatch",
                                 "straight_part_of": "nonlinear_spring"}]}
    assert effects_to_fit(spring) == ["nonlinear_spring", "stiffness_mismatch",
                                      "encoder_offset"]


def test_a_folded_group_member_is_fitted_from_a_real_verdict(baseline):
    """End to end: a LuGre friction's verdict names the hysteresis only in the group
    (tests/diagnosis/test_naming_rules.py); the calibration still fits it, after the
    friction."""
    from delta6.calibration.fit import effects_to_fit
    from delta6.diagnosis.run import diagnose

    from support.twinkit import lugre_friction_log
    verdict = diagnose(lugre_friction_log(baseline), baseline, seed=0)
    assert verdict["present"] == ["joint_friction"]
    assert effects_to_fit(verdict) == ["joint_friction", "spring_hysteresis"]


def test_an_iterate_that_leaves_the_models_domain_ends_the_fit_at_the_one_before(
        baseline, unit, monkeypatch):
    """A Gauss-Newton step that makes the model non-finite (an outside review's cable pulled a
    geometry fit past the trilateration's square root) ends the iterations at the iterate
    before it: the family is then judged by its plausibility, not reported as NaN beyond the
    file's bounds, and no numpy warning leaks."""
    from delta6.calibration.fit import _Fitter
    from delta6.core.calibration import neutral
    from delta6.diagnosis.data import GapData
    _, fit_run, _ = unit
    fitter = _Fitter(GapData.from_log(fit_run, baseline), neutral(baseline), None)
    blocks = np.arange(fitter.problem.n_blocks)
    one, latency = fitter.fit(neutral(baseline), ["stiffness_mismatch"], blocks, 1)
    real, calls = _Fitter.predict, []

    def poisoned(self, cal, latency=0.0):
        calls.append(cal)
        out = real(self, cal, latency)
        return out if len(calls) < 3 else out * np.nan      # the second iterate is bad
    monkeypatch.setattr(_Fitter, "predict", poisoned)
    with np.errstate(all="raise"):      # nothing may warn either
        got, got_latency = fitter.fit(neutral(baseline), ["stiffness_mismatch"], blocks, 3)
    assert len(calls) == 3
    np.testing.assert_array_equal(got.rate_ratio, one.rate_ratio)      # the first iterate
    assert got_latency == latency


@given(n_blocks=st.integers(8, 80), runs=st.integers(1, 6), width=st.integers(1, 3))
def test_the_held_out_runs_are_spread_over_the_log_and_buffered(n_blocks, runs, width):
    from delta6.calibration.fit import heldout_split
    from delta6.diagnosis.selection import BUFFER_BLOCKS
    if runs * (width + 2 * BUFFER_BLOCKS) > n_blocks:
        return
    held, train = heldout_split(n_blocks, runs * width, runs)
    assert len(held) == runs * width == len(set(held.tolist()))
    assert held.max() == n_blocks - 1                 # the last run is the log's tail
    share = n_blocks / runs
    for r in range(runs):                             # one run in each share of the log
        assert np.sum((held >= r * share - 1e-9) & (held < (r + 1) * share + 1e-9)) >= width
    gap = np.abs(train[:, None] - held[None, :]).min(axis=1)
    assert np.all(gap > BUFFER_BLOCKS)
    assert len(train) == n_blocks - len(np.unique(np.concatenate(
        [np.arange(max(b - BUFFER_BLOCKS, 0), min(b + BUFFER_BLOCKS + 1, n_blocks))
         for b in held])))


def test_a_log_that_loads_one_axis_at_a_time_is_scored_on_axes_its_training_loaded(baseline):
    """Weights hung axis by axis (the paper's Fig. 9 pushes): the log's last sixth loads Mz
    alone. Held out as one tail, the calibration was scored on an axis it never trained on
    (Mz 3 times the analytical model's p99); spread, every held-out run has its axis in the
    training blocks, and no axis is left worse."""
    from delta6.calibration.fit import worse_axes
    from delta6.twin.pushes import AxisPushes
    from delta6.twin.streams import stream
    effects = [twin.make_effect("stiffness_mismatch", 2, magnitude=0.8),
               twin.make_effect("geometry_error", 2, magnitude=0.8),
               twin.make_effect("backlash", 2, magnitude=0.6)]
    log = twin.simulate(baseline, effects, duration_s=600, rate_hz=50, seed=2,
                        path=AxisPushes(baseline, 600, stream(2, "pushes")))
    fit = calibrate(log, baseline, effects=["stiffness_mismatch", "geometry_error",
                                            "backlash"])
    before, after = (np.array(t["p99_pct"]) for t in (fit.heldout_before, fit.heldout_after))
    assert np.all(after < 0.6 * before), (before, after)
    assert worse_axes(fit.heldout_before, fit.heldout_after) == []
    assert not any(n.startswith("held-out ") for n in fit.notes)


def test_an_axis_left_worse_on_the_held_out_blocks_gets_a_note():
    from delta6.calibration.fit import worse_axes
    before = {"p99_pct": [1.0, 1.0, 1.0, 1.0, 1.0, 0.2]}
    same = worse_axes(before, {"p99_pct": [0.5, 1.02, 0.3, 0.3, 0.3, 0.209]})
    assert same == []                                # within the ladder's resolution
    notes = worse_axes(before, {"p99_pct": [0.5, 1.03, 0.3, 0.3, 0.3, 0.6]})
    assert [n.split(":")[0] for n in notes] == ["held-out Fy", "held-out Mz"]
    assert "0.60 % FS against the analytical model's 0.20" in notes[1]
