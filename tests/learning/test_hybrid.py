"""The hybrid: a residual model over a unit's calibration, evaluated on top of that calibration
and refused over any other."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from delta6.cli import main
from delta6.core import calibration as calibration_mod
from delta6.core.calibrated import CalibratedModel, counts_from_angles
from delta6.learning import LearnedEstimator, ModelFileError, fit
from delta6.learning.presets import preset
from delta6.link.logfile import read_log

from support.calibrations import history_calibration


@pytest.fixture(scope="module")
def hybrid(tmp_path_factory, baseline, unit_logs):
    folder = tmp_path_factory.mktemp("hybrid")
    cal = history_calibration(baseline, "unit-test", viscous_nm_s_per_rad=0.002)
    cal_path = calibration_mod.save(cal, folder / "unit.toml")
    chosen = preset("default", "mlp").with_recipe(max_epochs=1, epoch_fraction=0.3)
    fitted = fit.fit(read_log(unit_logs[0]), baseline, chosen, base="calibration",
                     calibration=cal, seed=2)
    path = folder / "hybrid.onnx"
    fit.write(fitted, path)
    return path, cal, cal_path


def test_the_model_card_names_the_calibration(hybrid):
    path, cal, _ = hybrid
    import onnx
    props = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    assert props["delta6.base"] == "calibration"
    assert props["delta6.calibration"] == "unit-test"
    assert props["delta6.calibration_hash"] == f"0x{cal.hash32():08x}"


def test_it_is_refused_without_or_over_another_calibration(hybrid, baseline):
    path, cal, _ = hybrid
    with pytest.raises(ModelFileError, match="residual over calibration unit-test .*give that"):
        LearnedEstimator(path, design=baseline)
    other = dataclasses.replace(cal, name="other", rate_ratio=np.ones(6))
    with pytest.raises(ModelFileError) as err:
        LearnedEstimator(path, design=baseline, calibration=other)
    assert "trained over calibration unit-test" in str(err.value) and "not other" in str(err.value)
    assert "\n" not in str(err.value)


def test_streaming_equals_batch_over_the_calibrated_model(hybrid, baseline, unit_logs):
    path, cal, _ = hybrid
    est = LearnedEstimator(path, design=baseline, calibration=cal)
    log = read_log(unit_logs[1])
    t, theta = log.t[:300].copy(), log.theta[:300].copy()
    theta[100, 0] = np.nan       # a failed read: no wrench, and the calibration's state waits
    batch = est.predict_arrays(t, theta)
    live = est.streaming()
    stream = np.array([live.update(ti, row) for ti, row in zip(t, theta)])
    assert np.array_equal(np.isnan(batch), np.isnan(stream))
    assert np.isnan(batch[100:125]).all() and np.isfinite(batch[125:]).all()
    scale = np.nanmax(np.abs(batch), axis=0)
    assert np.nanmax(np.abs(stream - batch) / scale) < 1e-6
    # in blocks, the calibration's state carried from one to the next
    live.reset()
    blocks = np.vstack([live.update_block(t[a:a + 43], theta[a:a + 43])
                        for a in range(0, 300, 43)])
    assert np.array_equal(np.isnan(blocks), np.isnan(batch))
    assert np.nanmax(np.abs(blocks - batch) / scale) < 1e-6
    # the base is the calibrated model run causally over the same samples
    finite = log.theta[:100]
    base = est.base.batch(log.t[:100], finite)
    expected, _ = CalibratedModel(baseline, cal).run(counts_from_angles(finite), 1 / est.rate_hz)
    assert np.allclose(base, expected, rtol=0, atol=1e-12)


def test_commands_train_and_evaluate_it_over_the_calibration(tmp_path, hybrid, unit_logs,
                                                             capsys):
    _, _, cal_path = hybrid
    model = tmp_path / "hyb.onnx"
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--residual-over", str(cal_path),
                 "--epochs", "1", "-o", str(model)]) == 0
    assert "residual over calibration unit-test" in capsys.readouterr().out
    table = tmp_path / "t.json"
    assert main(["evaluate", str(unit_logs[1]), "--calibration", str(cal_path), "--model",
                 str(model), "--json", str(table)]) == 0
    rows = json.loads(table.read_text())["rows"]
    assert [r["estimator"] for r in rows] == ["analytical", "calibrated", "hyb"]
    capsys.readouterr()
    assert main(["evaluate", str(unit_logs[1]), "--model", str(model)]) == 2
    err = capsys.readouterr().err.strip()
    assert "give that calibration" in err and "\n" not in err
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--residual-over", "nothing.txt",
                 "-o", str(model)]) == 2
    assert "'analytical' or a calibration file" in capsys.readouterr().err


def test_two_streams_on_one_estimator_are_each_the_batch(hybrid, baseline, unit_logs):
    # Each stream carries its own calibration state: fed in turns, neither sees the other's
    # samples.
    path, cal, _ = hybrid
    est = LearnedEstimator(path, design=baseline, calibration=cal)
    log = read_log(unit_logs[1])
    a = (log.t[:200], log.theta[:200])
    b = (log.t[200:400] - log.t[200], log.theta[200:400])
    want = [est.predict_arrays(*a), est.predict_arrays(*b)]
    streams = [est.streaming(), est.streaming()]
    got = [[], []]
    for i in range(200):
        for k, (t, theta) in enumerate((a, b)):
            got[k].append(streams[k].update(t[i], theta[i]))
    for k in (0, 1):
        scale = np.nanmax(np.abs(want[k]), axis=0)
        assert np.nanmax(np.abs(np.array(got[k]) - want[k]) / scale) < 1e-6, k
    # a reset starts that stream afresh, and only that one
    streams[0].reset()
    again = np.array([streams[0].update(t, th) for t, th in zip(*a)])
    assert np.nanmax(np.abs(again - want[0]) / np.nanmax(np.abs(want[0]), axis=0)) < 1e-6


def test_the_calibration_hash_is_read_as_a_number_and_required(hybrid, baseline, tmp_path):
    import onnx
    path, cal, _ = hybrid
    for value, ok in ((f"0x{cal.hash32():08X}", True), (None, False)):
        proto = onnx.load(str(path))
        for entry in list(proto.metadata_props):
            if entry.key == "delta6.calibration_hash":
                if value is None:
                    proto.metadata_props.remove(entry)
                else:
                    entry.value = value
        changed = tmp_path / f"h{ok}.onnx"
        onnx.save(proto, str(changed))
        if ok:      # upper-case digits are the same hash
            LearnedEstimator(changed, design=baseline, calibration=cal)
        else:
            with pytest.raises(ModelFileError, match="delta6.calibration_hash is missing"):
                LearnedEstimator(changed, design=baseline, calibration=cal)
