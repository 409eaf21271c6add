"""Fitting calibrations to twin runs: parameters recovered, held-out error shrinks on a run the
fit never saw, and clean data gets an empty calibration."""
from __future__ import annotations

import numpy as np
import pytest

from delta6 import twin
from delta6.calibration import calibrate
from delta6.calibration.fit import check_effects
from delta6.core.calibrated import CalibratedModel
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
    assert fit.chosen_by == "--effect" and fit.latency_s is None
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


@pytest.mark.parametrize("bad", [["thermal_drift"], ["warp_drive"]])
def test_uncorrectable_or_unknown_effects_are_refused(bad):
    with pytest.raises(UserError):
        check_effects(bad)


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
