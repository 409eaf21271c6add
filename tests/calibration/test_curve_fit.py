"""The two curve families (nonlinear_spring, encoder_periodic_error): the same physics as the
diagnosis's terms, and on the twin a unit with either effect alone calibrates down to the run
without it, on a run the fit never saw."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from delta6 import twin
from delta6.calibration import calibrate
from delta6.calibration.families import Context, families
from delta6.calibration.fit import with_straight_parts
from delta6.core import calibration as C
from delta6.core import curves
from delta6.core.calibrated import CalibratedModel, counts_from_angles
from delta6.core.model import ENCODER_COUNT_RAD
from delta6.core.spec import full_scale
from delta6.diagnosis import terms
from delta6.diagnosis.data import GapData

CURVES = ("nonlinear_spring", "encoder_periodic_error")


def test_the_curves_are_the_diagnosis_terms_own():
    assert curves.SPRING_REF_RAD == terms.NONLINEAR_REF_RAD
    assert curves.SPRING_STRAIGHT_PART == terms.NONLINEAR_STRAIGHT_PART
    assert curves.ENCODER_HARMONICS == terms.ENCODER_HARMONICS


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
