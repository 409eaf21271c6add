"""The on-chip residual over a unit's calibration: ``delta6 train --target mcu --residual-over
CAL.toml``, codegen refusing it without or over another calibration, and its Table V row in
``delta6 evaluate`` computed by the integer reference."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from delta6.cli import main
from delta6.core import calibration as calibration_mod
from delta6.core import int8net, residualmodel
from delta6.core.calibrated import CalibratedModel
from delta6.learning import mcu
from delta6.link.logfile import read_log

from support.calibrations import history_calibration


@pytest.fixture(scope="module")
def over_cal(tmp_path_factory, baseline, unit_logs):
    folder = tmp_path_factory.mktemp("mcu-cal")
    cal = history_calibration(baseline, "unit-cal")
    cal_path = calibration_mod.save(cal, folder / "unit.toml")
    other_path = calibration_mod.save(
        dataclasses.replace(cal, name="other", rate_ratio=np.ones(6)), folder / "other.toml")
    model_path = folder / "onchip.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--residual-over",
                 str(cal_path), "--epochs", "3", "--quiet", "-o", str(model_path)]) == 0
    return cal, cal_path, other_path, model_path


def test_the_model_names_the_calibration_it_corrects(over_cal):
    cal, _, _, model_path = over_cal
    model = residualmodel.load(model_path)
    assert model.base == "calibrated"
    # The default over a calibration: one linear layer over the counts (fits the 200 Hz loop).
    assert [f.kind for f in model.net.features] == ["counts"]
    assert [layer.shape for layer in model.net.layers] == [(6, 6)]
    assert (model.calibration_name, model.calibration_hash) == (cal.name, cal.hash32())


def test_codegen_takes_it_only_with_that_calibration(over_cal, tmp_path, capsys):
    _, cal_path, other_path, model_path = over_cal
    header = tmp_path / "generated" / "delta6_design.h"
    assert main(["codegen", "designs/delta6.toml", "--calibration", str(cal_path),
                 "--model", str(model_path), "-o", str(header)]) == 0
    assert (tmp_path / "generated" / "delta6_calibration.h").exists()
    assert (tmp_path / "generated" / "delta6_model.h").exists()
    assert main(["codegen", "designs/delta6.toml", "--calibration", str(cal_path),
                 "--model", str(model_path), "-o", str(header), "--check"]) == 0
    for argv, needle in ((["--model", str(model_path)], "give it with --calibration"),
                         (["--calibration", str(other_path), "--model", str(model_path)],
                          "trained over calibration 'unit-cal'")):
        capsys.readouterr()
        assert main(["codegen", "designs/delta6.toml", *argv, "-o", str(header)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err, err


def test_an_analytical_model_is_refused_over_a_calibration(trained_analytical, over_cal,
                                                           tmp_path, capsys):
    _, cal_path, _, _ = over_cal
    assert main(["codegen", "designs/delta6.toml", "--calibration", str(cal_path), "--model",
                 str(trained_analytical), "-o", str(tmp_path / "generated" / "d.h")]) == 2
    assert "corrects the analytical model" in capsys.readouterr().err


@pytest.fixture(scope="module")
def trained_analytical(tmp_path_factory, unit_logs):
    path = tmp_path_factory.mktemp("mcu-an") / "plain.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--epochs", "2", "--hidden",
                 "8", "--quiet", "-o", str(path)]) == 0
    return path


def test_evaluate_row_is_the_integer_reference_over_the_calibration(over_cal, baseline,
                                                                    unit_logs, tmp_path):
    cal, cal_path, _, model_path = over_cal
    out = tmp_path / "table.json"
    assert main(["evaluate", str(unit_logs[1]), "--calibration", str(cal_path), "--model",
                 str(model_path), "--json", str(out)]) == 0
    rows = {r["estimator"]: r for r in json.loads(out.read_text())["rows"]}
    assert list(rows) == ["analytical", "calibrated", "onchip"]
    # The row is the calibrated wrench plus the integer network's correction, run sample by
    # sample with its state carried over (as the board runs it), not in one batch.
    log = read_log(unit_logs[1])
    model = residualmodel.load(model_path)
    base = CalibratedModel(baseline, cal).predict(log)
    u, counts, valid = mcu.board_inputs(log, baseline, base, model.net.input_scale)
    state, corrections = None, []
    for i in range(len(log)):
        c, state = int8net.run(model.net, u[i:i + 1], counts[i:i + 1], valid=valid[i:i + 1],
                               state=state)
        corrections.append(c[0])
    expected = int8net.apply_output(base, np.array(corrections), model.net.output_step)
    got = mcu.McuEstimator(model_path, baseline, cal).predict(log)
    assert np.array_equal(got, expected.astype(float))
    assert not np.array_equal(got, base)   # the network does correct something
    from delta6.core import accuracy
    from delta6.core.spec import full_scale
    p = accuracy.percentiles(got, log.wrench, full_scale(baseline), (99,))
    assert np.allclose(rows["onchip"]["p99_pct"], p["p99"])


def _widened(model_path, out_path, width: int):
    """The trained one-hidden-layer model with its hidden layer repeated up to ``width``
    neurons: a valid model file too costly for a board (train refuses to make one)."""
    body = json.loads(model_path.read_text())
    first, last = body["network"]["layers"]
    reps = -(-width // len(first["weights"]))
    for key in ("weights", "bias", "multiplier", "shift"):
        first[key] = (first[key] * reps)[:width]
    last["weights"] = [(row * reps)[:width] for row in last["weights"]]
    out_path.write_text(json.dumps(body))
    return out_path


def test_a_model_too_costly_for_the_rated_rate_is_refused(over_cal, unit_logs, tmp_path,
                                                          capsys):
    """Over a calibration the board keeps 200 Hz with at most MAX_MODEL_MACS['calibrated']
    multiply-accumulates: train refuses to make a bigger network (before training), codegen
    and evaluate refuse a bigger model file, each in one line; a smaller one is taken."""
    from delta6.commands.codegen import MAX_MODEL_MACS
    _, cal_path, _, _ = over_cal
    header = tmp_path / "generated" / "delta6_design.h"
    costly = tmp_path / "h16.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--residual-over",
                 str(cal_path), "--epochs", "1", "--hidden", "16", "--quiet",
                 "-o", str(costly)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "192 multiply-accumulates" in err, err
    assert "at most 144" in err and not costly.exists()
    small = tmp_path / "h4.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--residual-over",
                 str(cal_path), "--epochs", "1", "--hidden", "4", "--quiet",
                 "-o", str(small)]) == 0
    _widened(small, costly, 16)
    for model, ok in ((small, True), (costly, False)):
        macs = residualmodel.load(model).net.macs
        assert (macs <= MAX_MODEL_MACS["calibrated"]) == ok, macs
        for command in (["codegen", "designs/delta6.toml", "-o", str(header)],
                        ["evaluate", str(unit_logs[1])]):
            capsys.readouterr()
            status = main([*command, "--calibration", str(cal_path), "--model", str(model)])
            err = capsys.readouterr().err.strip()
            if ok:
                assert status == 0, err
            else:
                assert status == 2 and len(err.splitlines()) == 1 and "at most 144" in err, err


def test_over_a_calibration_with_curves_only_the_default_model_is_taken(over_cal, unit_logs,
                                                                        tmp_path, capsys):
    """The curve tables take about 2,200 cycles and 1,560 B more: over such a calibration the
    board keeps 200 Hz (and the emulated ATmega328P's 32 KB) with the default linear map of
    the counts (36 multiply-accumulates), not with a hidden layer: train refuses one, codegen
    refuses a model trained over the calibration without curves."""
    from support.calibrations import with_curves
    cal, cal_path, _, _ = over_cal
    curved = calibration_mod.save(with_curves(cal, 4).with_(name="curved"), tmp_path / "c.toml")
    header = tmp_path / "generated" / "delta6_design.h"
    model = tmp_path / "h0.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--residual-over",
                 str(curved), "--epochs", "1", "--quiet", "-o", str(model)]) == 0
    capsys.readouterr()
    assert main(["codegen", "designs/delta6.toml", "--calibration", str(curved),
                 "--model", str(model), "-o", str(header)]) == 0
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--residual-over",
                 str(curved), "--epochs", "1", "--quiet", "--hidden", "4",
                 "-o", str(tmp_path / "h4.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "at most 36" in err, err
