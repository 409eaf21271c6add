"""Training on twin logs: it learns, it is reproducible, and its model card says what it did."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from delta6 import twin
from delta6.core import accuracy
from delta6.core.spec import full_scale
from delta6.learning import LearnedEstimator, fit, training
from delta6.learning.presets import preset
from delta6.link.logfile import read_log


@pytest.fixture(scope="module")
def mismatch_logs(tmp_path_factory, baseline):
    """A unit with a large spring-rate mismatch and backlash (learnable over the analytical
    model: linear in the load, and a function of the recent motion), a calibration run and a
    second run of the same unit."""
    folder = tmp_path_factory.mktemp("mismatch")
    effects = [twin.make_effect("stiffness_mismatch", seed=5, magnitude=1.0),
               twin.make_effect("backlash", seed=5, magnitude=1.0)]
    first = twin.simulate(baseline, effects, duration_s=200, seed=11)
    again = twin.simulate(baseline, twin.effects_from_truth(first.truth), duration_s=60, seed=12)
    return (twin.write_log(first, folder / "cal.csv")[0],
            twin.write_log(again, folder / "eval.csv")[0])


def test_a_few_epochs_beat_the_analytical_model_on_another_run(tmp_path, baseline, mismatch_logs):
    cal, other = mismatch_logs
    chosen = preset("default", "mlp").with_recipe(max_epochs=6, epoch_fraction=1.0, batch=64)
    fitted = fit.fit(read_log(cal), baseline, chosen, base="analytical", seed=0, threads=1)
    fit.write(fitted, tmp_path / "m.onnx")
    est = LearnedEstimator(tmp_path / "m.onnx", design=baseline)
    log = read_log(other)
    fs = full_scale(baseline)
    learned = accuracy.percentiles(est.predict(log), log.wrench, fs, (99,))["p99"]
    analytical = accuracy.percentiles(est.base.batch(log.t, log.theta), log.wrench, fs,
                                      (99,))["p99"]
    assert all(lv < 0.7 * av for lv, av in zip(learned, analytical)), (learned, analytical)
    summary = fitted.card.training
    assert summary["epochs"] == 6 and summary["samples"] == 10000
    assert all(m < b for m, b in zip(summary["holdout_pct_fs"]["p99"],
                                     summary["holdout_base_pct_fs"]["p99"]))


def test_end_to_end_training_lowers_the_held_out_loss(baseline, unit_logs):
    chosen = preset("default", "gru").with_recipe(max_epochs=3, epoch_fraction=1.0, batch=64)
    fitted = fit.fit(read_log(unit_logs[0]), baseline, chosen, seed=1, threads=1)
    losses = [r.holdout_loss for r in fitted.trained.history]
    data = fitted.data
    predict_the_mean = float(((data.targets[data.split():] - data.targets[:data.split()].mean(0))
                              ** 2).mean())
    assert losses[-1] < losses[0] and losses[-1] < 0.1 * predict_the_mean, (losses,
                                                                             predict_the_mean)


def test_training_is_reproducible(baseline, unit_logs):
    log = read_log(unit_logs[0])
    chosen = preset("default", "mlp").with_recipe(max_epochs=2, epoch_fraction=0.3)
    runs = [fit.fit(log, baseline, chosen, seed=4, threads=1) for _ in range(2)]
    other = fit.fit(log, baseline, chosen, seed=5, threads=1)
    weights = [torch.cat([p.flatten() for p in r.trained.module.parameters()]) for r in
               runs + [other]]
    assert torch.equal(weights[0], weights[1])
    assert not torch.equal(weights[0], weights[2])
    assert [r.holdout_loss for r in runs[0].trained.history] == \
        [r.holdout_loss for r in runs[1].trained.history]


def test_early_stopping_keeps_the_best_checkpoint(baseline, unit_logs):
    log = read_log(unit_logs[0])
    chosen = preset("default", "mlp").with_recipe(max_epochs=30, patience=2, lr=0.05,
                                                   lr_decay_patience=0, epoch_fraction=0.2)
    fitted = fit.fit(log, baseline, chosen, seed=0, threads=1)
    history = fitted.trained.history
    best = min(history, key=lambda r: r.holdout_loss)
    data = fitted.data
    split = data.split()
    x = torch.from_numpy(data.inputs[split:])
    y = torch.from_numpy(data.targets[split:])
    assert training.mse(fitted.trained.module, x, y) == pytest.approx(best.holdout_loss, rel=1e-5)
    if len(history) < 30:
        assert "early stop" in fitted.trained.stopped
        assert history[-1].epoch - best.epoch == 2


def test_a_log_of_another_design_is_refused(tmp_path, baseline, unit_logs):
    from delta6.core.design import load
    from delta6.core.errors import UserError
    from delta6.core.paths import DESIGNS_DIR

    other = load(DESIGNS_DIR / "stiff.toml")
    with pytest.raises(UserError, match="recorded with design delta6"):
        fit.fit(read_log(unit_logs[0]), other, preset("default", "mlp"))


def test_training_rows_with_missing_angles_are_left_out(baseline, unit_logs):
    log = read_log(unit_logs[0])
    log.theta[100, 2] = np.nan
    chosen = preset("default", "mlp").with_recipe(max_epochs=1, epoch_fraction=0.1)
    fitted = fit.fit(log, baseline, chosen)
    assert len(fitted.data) == len(log) - 25        # the windows holding row 100
    assert np.isfinite(fitted.data.inputs).all()
