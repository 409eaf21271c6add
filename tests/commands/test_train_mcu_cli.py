"""``delta6 train --target mcu`` and ``delta6 codegen --model``: train on a twin log, the
model file, its ONNX float network, the header, and one-line errors with exit status 2."""
from __future__ import annotations

import json

import numpy as np
import pytest

from delta6.cli import main
from delta6.core import int8net, residualmodel
from delta6.learning import mcu
from delta6.link.logfile import read_log


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A model trained for a few epochs on 200 s of the paper scenario with a strong,
    learnable effect added (spring hysteresis, which the analytical model lacks)."""
    tmp = tmp_path_factory.mktemp("train")
    log = tmp / "cal.csv"
    assert main(["simulate", "--scenario", "spring_hysteresis", "--magnitude", "1",
                 "--duration", "200", "--seed", "4", "-o", str(log)]) == 0
    model = tmp / "unit.json"
    assert main(["train", str(log), "--target", "mcu", "--epochs", "15", "--hidden", "12",
                 "--quiet", "-o", str(model)]) == 0
    return log, model


def test_training_beats_the_analytical_model_on_the_held_out_tail(trained):
    _, path = trained
    model = residualmodel.load(path)
    p99 = model.training["heldout_p99_pct"]
    assert np.mean(p99["int8"]) < 0.85 * np.mean(p99["base"])
    assert max(abs(x) for x in model.training["quantization_loss_p99_pct"]) < 0.1


def test_onnx_float_network_equals_the_numpy_one(trained):
    log_path, path = trained
    model = residualmodel.load(path)
    log = read_log(log_path)
    from delta6.core.design import load
    design = load("designs/delta6.toml")
    u, counts, valid = mcu.board_inputs(log, design, mcu.AnalyticalBase(design).predict(log),
                                        model.net.input_scale)
    v = int8net.feature_values(model.net.features, u, counts, valid=valid)
    got = mcu.onnx_correction(path.with_suffix(".onnx"), v)
    # The ONNX file is the float network the int8 one was quantized from: it must track it.
    int_corr, _ = int8net.run(model.net, u, counts, valid=valid)
    int_n = int_corr * model.net.output_step
    scale = np.percentile(np.abs(got), 99, axis=0)
    assert np.all(np.percentile(np.abs(got - int_n), 99, axis=0) <= 0.05 * scale)


def test_codegen_writes_and_removes_the_model_header(trained, tmp_path, capsys):
    _, path = trained
    header = tmp_path / "generated" / "delta6_design.h"
    assert main(["codegen", "designs/delta6.toml", "--model", str(path), "-o", str(header)]) == 0
    text = (tmp_path / "generated" / "delta6_model.h").read_text()
    model = residualmodel.load(path)
    assert f"kHash = 0x{model.hash32():08X}UL" in text and "GENERATED FILE" in text
    assert main(["codegen", "designs/delta6.toml", "--model", str(path), "-o", str(header),
                 "--check"]) == 0
    assert main(["codegen", "designs/delta6.toml", "-o", str(header), "--check"]) == 1
    assert main(["codegen", "designs/delta6.toml", "-o", str(header)]) == 0
    assert not (tmp_path / "generated" / "delta6_model.h").exists()
    assert "removed" in capsys.readouterr().out


def test_the_committed_tree_has_no_model_header(root):
    assert not (root / "firmware" / "include" / "generated" / "delta6_model.h").exists()


def test_bad_inputs_are_one_line_errors(trained, tmp_path, capsys):
    log, path = trained
    data = json.loads(path.read_text())
    data["design"]["hash"] = "0x00000001"
    other = tmp_path / "other.json"
    other.write_text(json.dumps(data))
    broken = tmp_path / "broken.json"
    broken.write_text(path.read_text()[:200])
    out = str(tmp_path / "x" / "delta6_design.h")
    cases = [
        (["codegen", "designs/delta6.toml", "--model", str(other), "-o", out], "trained for"),
        (["codegen", "designs/delta6.toml", "--model", str(broken), "-o", out], "not JSON"),
        (["codegen", "designs/delta6.toml", "--model", str(tmp_path / "none.json"), "-o", out],
         "no such file"),
        (["train", str(log), "--target", "mcu", "--hidden", "49", "-o", str(tmp_path / "m.json")],
         "--hidden"),
        (["train", str(log), "--target", "mcu", "-o", str(tmp_path / "m.onnx")], "JSON"),
        (["train", str(tmp_path / "none.csv"), "--target", "mcu", "-o", str(tmp_path / "m.json")],
         "none.csv"),
    ]
    for argv, needle in cases:
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err, (argv, err)


def _refused_mcu_training(log, tmp_path, capsys) -> str:
    """``delta6 train LOG --target mcu`` refused: exit 2, one line on stderr (returned), and
    no model file."""
    capsys.readouterr()
    assert main(["train", str(log), "--target", "mcu", "--epochs", "1", "--quiet",
                 "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert not (tmp_path / "m.json").exists()
    return err


def test_a_log_of_another_design_is_refused_before_training(tmp_path, capsys):
    # The board runs the model on one design: training it on another design's log would
    # write a model that silently corrects the wrong mechanism.
    log = tmp_path / "stiff.csv"
    assert main(["simulate", "--design", "designs/stiff.toml", "--duration", "20",
                 "-o", str(log)]) == 0
    err = _refused_mcu_training(log, tmp_path, capsys)
    assert "recorded with design stiff" in err, err


def test_an_output_that_cannot_be_written_is_refused_before_training(tmp_path, capsys):
    log = tmp_path / "cal.csv"
    assert main(["simulate", "--duration", "40", "-o", str(log)]) == 0
    cases = [
        (["--target", "mcu", "-o", str(tmp_path / "none" / "m.json")], "does not exist"),
        (["--target", "mcu", "-o", str(tmp_path / "m.json")], "is a folder"),  # m.onnx below
        (["--model", "mlp", "-o", str(tmp_path)], "is a folder"),
        (["--model", "mlp", "-o", str(tmp_path / "none" / "m.onnx")], "does not exist"),
    ]
    (tmp_path / "m.onnx").mkdir()
    for options, words in cases:
        capsys.readouterr()
        assert main(["train", str(log), "--epochs", "1", *options]) == 2, options
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err and "epoch" not in err, (options, err)
    assert not (tmp_path / "m.json").exists()


def test_a_network_the_quantizer_refuses_is_one_line(tmp_path, capsys, monkeypatch):
    # Whatever the integer engine cannot represent after the training is a UserError line,
    # not a ValueError traceback, and no model file.
    from delta6.core import int8quant

    def refuse(*args, **kwargs):
        raise ValueError("output_step: out of range")
    monkeypatch.setattr(int8quant, "quantize", refuse)
    log = tmp_path / "cal.csv"
    assert main(["simulate", "--duration", "40", "-o", str(log)]) == 0
    err = _refused_mcu_training(log, tmp_path, capsys)
    assert "cannot be quantized" in err and "output_step: out of range" in err, err


def test_the_axes_a_model_makes_worse_are_named():
    from delta6.commands.train import worse_axes
    assert worse_axes([1.0, 2.0, 0.5, 0.4, 0.3, 0.2], [1.0, 1.5, 0.6, 0.3, 0.3, 0.1]) == [
        "Fy", "Mx", "Mz"]
    assert worse_axes([0.1] * 6, [0.2] * 6) == []


def test_a_log_at_a_rate_no_board_samples_at_is_refused(tmp_path, capsys):
    """The model's step features count samples of its rate: trained at 37.5 Hz and labelled
    37 Hz, it would have run at a rate it was not trained at."""
    log = tmp_path / "odd.csv"
    assert main(["simulate", "--duration", "20", "--rate", "37.5", "-o", str(log)]) == 0
    err = _refused_mcu_training(log, tmp_path, capsys)
    assert "sampled at 37.5 Hz, not a whole number" in err, err
