"""The two curve families (nonlinear_spring, encoder_periodic_error): the same physics as the
diagnosis's terms, and on the twin a unit with either effect alone calibrates down to the run
without it, on a run the fit never saw."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from delta6 import twin
from delta6.calibration import calibrate
from delta6.calibration.families import Context, curve_table_checks, families, without_vanishing_curves
from delta6.calibration.fit import with_straight_parts
from delta6.core import calibration as C
from delta6.core import curves
from delta6.core.calibrated import CalibratedModel, counts_from_angles
from delta6.core.design import load as load_design
from delta6.core.model import ENCODER_COUNT_RAD
from delta6.core.spec import full_scale
from delta6.diagnosis import terms
from delta6.diagnosis.data import GapData

from conftest import DESIGNS

CURVES = ("nonlinear_spring", "encoder_periodic_error")


def test_the_families_columns_are_the_terms_columns_at_the_count_angle(baseline):
    run = twin.simulate(baseline, [], duration_s=40, rate_hz=50, seed=2)
    # A log of whole counts (what the board has): the term's columns there are the family's.
    run = dataclasses.replace(run, theta=counts_from_angles(run.theta) * ENCODER_COUNT_RAD)
    data = GapData.from_log(run, baseline)
    cal = C.neutral(baseline)
    model_terms, _ = CalibratedModel(baseline, cal).joint_terms(counts_from_angles(data.theta),
                                                               0.02)
    fams = families(cal)
    by_name = {t.name: t for t in terms.TERMS}
    for name in CURVES:
        fam = fams[name]
        np.testing.assert_array_equal(fam.term_map, np.eye(len(by_name[name].param_names)))
        assert fam.prior_sd == by_name[name].prior_sd
        got = fam.columns(Context(data, model_terms, cal))
        want = by_name[name].build(data)
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())


def test_a_spring_curve_is_fitted_with_its_rate():
    assert with_straight_parts(["nonlinear_spring"]) == ["nonlinear_spring", "stiffness_mismatch"]
    assert with_straight_parts(["stiffness_mismatch", "nonlinear_spring"]) \
        == ["stiffness_mismatch", "nonlinear_spring"]


@pytest.mark.parametrize("name,magnitude", [("nonlinear_spring", 1.0),
                                            ("encoder_periodic_error", 1.0)])
def test_a_curve_alone_is_calibrated_out_on_an_unseen_run(baseline, name, magnitude):
    """The twin's effect (its own formulation, not the family's: a cubic spring or a
    progressive one, a magnet's harmonics at the true angle) at full magnitude leaves the
    analytical model far from the reference; the calibration brings an unseen run of the same
    unit to within a quarter of the run without the effect (the twin's floor: noise, the
    reference's own error)."""
    effect = twin.make_effect(name, 5, magnitude=magnitude)
    fit_run = twin.simulate(baseline, [effect], duration_s=120, rate_hz=50, seed=5)
    check = twin.simulate(duration_s=60, rate_hz=50, **twin.same_unit(fit_run.truth, 6))
    fit = calibrate(fit_run, baseline, effects=[name])
    assert name in fit.calibration.effects and curves.has_curves(baseline, fit.calibration)
    fs = full_scale(baseline)
    before = np.percentile(np.abs(check.model_wrench() - check.wrench) / fs * 100, 99, axis=0)
    after = np.percentile(np.abs(CalibratedModel(baseline, fit.calibration).predict(check)
                                 - check.wrench) / fs * 100, 99, axis=0)
    floor = np.asarray(twin.simulate(**twin.without(check.truth, [name])).gap((99,))["p99"])
    # A curve the calibration did not correct would leave `before` (the largest axis 1.5-3
    # times the floor at this magnitude).
    assert before.max() > 1.5 * floor.max(), (before, floor)
    assert np.all(after <= 1.25 * floor), (before, after, floor)


def test_a_curve_that_fits_only_beyond_the_boards_table_is_left_out_not_fatal(baseline):
    """A 25 % rate error fitted with the encoder curve alone: the curve's iterates leave the
    board's angle table (+-0.0625 rad); the fit holds them at its range, then leaves the
    family out as implausible and writes the calibration, saying so."""
    effect = twin.make_effect("stiffness_mismatch", 3, deviation=(0.25,) * 6)
    run = twin.simulate(baseline, [effect], duration_s=60, rate_hz=50, seed=3)
    fit = calibrate(run, baseline, effects=["encoder_periodic_error"])
    cal = fit.calibration
    assert cal.fit["left_out"] == ["encoder_periodic_error"]
    assert any(n.startswith("encoder_periodic_error: left out") and "board_table_angle_rad" in n
               for n in fit.notes), fit.notes
    assert not curves.has_curves(baseline, cal)
    CalibratedModel(baseline, cal)                  # the written calibration is the board's


def test_a_plausible_spring_curve_beyond_the_torque_table_is_implausible():
    """On a stiff design (k = 0.96 N*m/rad) a spring curve, an encoder curve, an offset and a
    rate each within the diagnosis's plausible limits fill the torque table beyond its
    +-0.5 N*m: the spring's check (the larger part at the worst knot) says so."""
    stiff = load_design(DESIGNS / "stiff.toml")
    # e = a sin(q), -0.03 rad at 0.5 rad (+0.032 at the lower end knot, -0.54 rad, where
    # the spring's angle q - offset - e is -0.62 rad).
    a = -0.03 / np.sin(0.5)
    cal = C.neutral(stiff).with_(spring_curvature=np.full((6, 2), 0.58),
                                 encoder_periodic_rad=np.tile(np.eye(8)[0] * a, (6, 1)),
                                 offset_rad=np.full(6, 0.049), rate_ratio=np.full(6, 1.3))
    fams = families(cal)
    for name in ("nonlinear_spring", "encoder_periodic_error", "encoder_offset",
                 "stiffness_mismatch"):
        assert fams[name].implausible(cal) == [], name
    with pytest.raises(curves.CurveRangeError, match="torque"):
        curves.curve_tables(stiff, cal)
    spring = curve_table_checks(stiff, cal, "nonlinear_spring")
    encoder = curve_table_checks(stiff, cal, "encoder_periodic_error")
    assert max(c["ratio"] for c in spring) > 1.0
    assert max(c["ratio"] for c in encoder) <= 1.0
    assert curve_table_checks(stiff, cal, "stiffness_mismatch") == []


def test_a_fitted_curve_that_rounds_to_nothing_is_written_as_zero(baseline):
    cal = C.neutral(baseline).with_(spring_curvature=np.full((6, 2), 1e-7),
                                    encoder_periodic_rad=np.full((6, 8), 1e-9))
    out = without_vanishing_curves(baseline, cal)
    assert not np.any(out.spring_curvature) and not np.any(out.encoder_periodic_rad)
    assert out.hash32() == C.neutral(baseline).hash32()
    kept = cal.with_(spring_curvature=np.full((6, 2), 0.1))
    out = without_vanishing_curves(baseline, kept)
    np.testing.assert_array_equal(out.spring_curvature, kept.spring_curvature)
    assert not np.any(out.encoder_periodic_rad)
