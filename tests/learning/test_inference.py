"""Serving a model: batch and streaming agree, the wrong model or file is refused in one line,
and nothing on the inference path needs torch."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper

from delta6.cli import main
from delta6.core.design import load
from delta6.core.paths import DESIGNS_DIR
from delta6.learning import LearnedEstimator, ModelFileError
from delta6.link.device import Device
from delta6.link.logfile import read_log

KINDS = ("mlp", "lstm", "gru", "transformer")


@pytest.mark.parametrize("kind", KINDS)
def test_streaming_equals_batch_sample_for_sample(tiny_models, baseline, unit_logs, kind):
    log = read_log(unit_logs[1])
    n = 400
    t, theta = log.t[:n].copy(), log.theta[:n].copy()
    t[250:] += 0.5              # lost samples: the window starts again
    theta[120, 3] = np.nan      # a failed encoder read: no wrench while it is in the window
    est = LearnedEstimator(tiny_models[kind][0], design=baseline)
    batch = est.predict_arrays(t, theta)
    live = est.streaming()
    stream = np.array([live.update(ti, row) for ti, row in zip(t, theta)])
    assert np.array_equal(np.isnan(batch), np.isnan(stream))
    assert np.isnan(batch[120:145]).all() and np.isfinite(batch[145:]).all()
    assert np.isfinite(batch[:120]).all()
    scale = np.nanmax(np.abs(batch), axis=0)
    assert np.nanmax(np.abs(stream - batch) / scale) < 1e-6
    # the same after a reset and in blocks of any length (the gap and the failed read
    # inside blocks and across their edges)
    for edges in ([0, 50, 400], [0, 1, 2, 119, 121, 249, 251, 300, 400],
                  [0, *range(7, 400, 37), 400]):
        live.reset()
        blocks = np.vstack([live.update_block(t[a:b], theta[a:b])
                            for a, b in zip(edges[:-1], edges[1:])])
        assert np.array_equal(np.isnan(blocks), np.isnan(batch))
        assert np.nanmax(np.abs(blocks - batch) / scale) < 1e-6


def test_predict_on_a_log_matches_the_arrays(tiny_models, baseline, unit_logs):
    log = read_log(unit_logs[1])
    est = LearnedEstimator(tiny_models["mlp"][0], design=baseline)
    assert est.name == "mlp"
    out = est.predict(log)
    assert out.shape == (len(log), 6) and np.isfinite(out).all()
    assert np.array_equal(out, est.predict_arrays(log.t, log.theta))


def test_a_model_for_another_design_is_refused(tiny_models):
    stiff = load(DESIGNS_DIR / "stiff.toml")
    with pytest.raises(ModelFileError) as err:
        LearnedEstimator(tiny_models["gru"][0], design=stiff)
    message = str(err.value)
    assert "trained for design delta6 (0x535534af), not stiff" in message
    assert "\n" not in message


def test_a_log_at_another_rate_is_refused(tiny_models, baseline, unit_logs):
    log = read_log(unit_logs[1])
    log.t = log.t * 0.2      # 250 Hz
    with pytest.raises(ModelFileError, match="sampled at 250 Hz.*trained at 50 Hz"):
        LearnedEstimator(tiny_models["mlp"][0], design=baseline).predict(log)


def foreign_model(path, shape=(1, 25, 6), props=None):
    x = helper.make_tensor_value_info("x", TensorProto.FLOAT, list(shape))
    y = helper.make_tensor_value_info("y", TensorProto.FLOAT, list(shape))
    graph = helper.make_graph([helper.make_node("Identity", ["x"], ["y"])], "g", [x], [y])
    proto = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    for key, value in (props or {}).items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(proto, str(path))
    return path


def graph_model(path, props, *, dtype=TensorProto.FLOAT, batch="N", out_dtype=None,
                reshape=None):
    """A graph of the right rank that averages the window: (batch, 25, 6) -> (batch, 6), with
    the input of ``dtype``, the batch fixed if ``batch`` is a number, the output cast to
    ``out_dtype``, or ``reshape`` (the window to that fixed shape first)."""
    x = helper.make_tensor_value_info("x", dtype, [batch, 25, 6])
    nodes, inits, last = [], [], "x"
    if reshape is not None:
        inits.append(helper.make_tensor("shape", TensorProto.INT64, [len(reshape)], reshape))
        nodes.append(helper.make_node("Reshape", ["x", "shape"], ["r"]))
        last = "r"
    nodes.append(helper.make_node("ReduceMean", [last], ["m"], axes=[-2], keepdims=0))
    last = "m"
    if out_dtype is not None:
        nodes.append(helper.make_node("Cast", ["m"], ["c"], to=out_dtype))
        last = "c"
    y = helper.make_tensor_value_info(last, out_dtype or dtype, [batch, 6])
    graph = helper.make_graph(nodes, "g", [x], [y], initializer=inits)
    proto = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    for key, value in props.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(proto, str(path))
    return path


def bad_files(tmp_path, good):
    """(file, words its one-line refusal contains)."""
    data = good.read_bytes()
    card = {p.key: p.value for p in onnx.load(str(good)).metadata_props}
    cases = {
        "missing.onnx": (None, "no such file"),
        "empty.onnx": (b"", "not a readable ONNX model"),
        "truncated.onnx": (data[: len(data) // 2], "not a readable ONNX model"),
        "noise.onnx": (np.random.default_rng(0).bytes(5000), "not a readable ONNX model"),
        "text.onnx": (b"t,theta_e1\n0,1\n", "not a readable ONNX model"),
    }
    out = []
    for name, (content, words) in cases.items():
        if content is not None:
            (tmp_path / name).write_bytes(content)
        out.append((tmp_path / name, words))
    (tmp_path / "folder.onnx").mkdir()
    out.append((tmp_path / "folder.onnx", "a folder, not a model file"))
    out.append((foreign_model(tmp_path / "foreign.onnx"), "not a Delta6 learned estimator"))
    out.append((foreign_model(tmp_path / "shape.onnx", props=card),
                "does not take (batch, 25, 6) windows"))
    for name, options, words in (
            ("double", {"dtype": TensorProto.DOUBLE}, "input is tensor(double)"),
            ("half", {"dtype": TensorProto.FLOAT16}, "input is tensor(float16)"),
            ("int64-out", {"out_dtype": TensorProto.INT64}, "output is tensor(int64)"),
            ("double-out", {"out_dtype": TensorProto.DOUBLE}, "output is tensor(double)"),
            ("batch-1", {"batch": 1}, "does not take (batch, 25, 6) windows")):
        out.append((graph_model(tmp_path / f"{name}.onnx", card, **options), words))
    norm = json.loads(card["delta6.normalisation"])
    for key, value, words in (("delta6.normalisation", "{", "normalisation is unusable"),
                              ("delta6.window", "-3", "window must be"),
                              ("delta6.schema", "delta6-learned/99", "not supported"),
                              ("delta6.kind", "cnn", "names no known model"),
                              ("delta6.training", "[1]", "training must be a JSON object"),
                              ("delta6.design_hash", "0x1234567890", "does not fit 32 bits"),
                              ("delta6.calibration_hash", "0x12345678",
                               "calibration_hash belongs to a model over a calibration"),
                              ("delta6.colour", "blue", "delta6.colour is not a key"),
                              ("delta6.normalisation",
                               json.dumps({**norm, "theta_scale": [1e-300] * 6}),
                               "theta_scale must lie in 1e-09..1e+06"),
                              ("delta6.normalisation",
                               json.dumps({**norm, "target_scale": [1e300] * 6}),
                               "target_scale must lie in 1e-09..1e+06")):
        proto = onnx.load(str(good))
        for entry in proto.metadata_props:
            if entry.key == key:
                entry.value = value
        if key not in card:
            entry = proto.metadata_props.add()
            entry.key, entry.value = key, value
        path = tmp_path / f"tampered-{key.split('.')[1]}-{len(out)}.onnx"
        onnx.save(proto, str(path))
        out.append((path, words))
    return out


def test_corrupt_or_foreign_files_get_one_line(tmp_path, tiny_models, baseline):
    for path, words in bad_files(tmp_path, tiny_models["mlp"][0]):
        with pytest.raises(ModelFileError) as err:
            LearnedEstimator(path, design=baseline)
        assert words in str(err.value) and "\n" not in str(err.value), (path.name, err.value)


def test_the_stream_command_refuses_them_with_exit_2(tmp_path, tiny_models, capsys):
    for path, words in bad_files(tmp_path, tiny_models["mlp"][0])[:7]:
        assert main(["stream", "--port", "delta6sim://", "--model", str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err and err.startswith("delta6 stream: error:")


def test_inference_imports_no_torch(tiny_models, unit_logs):
    code = (
        "import sys\n"
        "from delta6.core.design import load\n"
        "from delta6.core.paths import DEFAULT_DESIGN\n"
        "from delta6.learning import LearnedEstimator\n"
        "import delta6.commands.stream\n"
        "from delta6.link.logfile import read_log\n"
        f"est = LearnedEstimator({str(tiny_models['gru'][0])!r}, design=load(DEFAULT_DESIGN))\n"
        f"w = est.predict(read_log({str(unit_logs[1])!r}))\n"
        "live = est.streaming(); live.update(0.0, [0.01] * 6)\n"
        "assert 'torch' not in sys.modules, 'torch was imported'\n"
        "print(w.shape)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(3000, 6)"


def test_with_a_device_the_stream_equals_the_log(tiny_models, baseline):
    est = LearnedEstimator(tiny_models["gru"][0], design=baseline)
    live = est.streaming()
    with Device("delta6sim://?motion=sine&rate=50") as dev:
        live.check_device(dev.info())
        dev.set_mode("raw")
        dev.start(50)
        got = []
        for sample, wrench in live.wrap(dev.samples(timeout=2.0)):
            got.append((sample.t, sample.theta, wrench))
            if len(got) == 60:
                break
        dev.stop()
    t = np.array([g[0] for g in got])
    theta = np.array([g[1] for g in got])
    streamed = np.array([g[2] for g in got])
    assert np.allclose(streamed, est.predict_arrays(t, theta), rtol=1e-6, atol=1e-9)


def test_a_device_of_another_design_is_refused(tiny_models, baseline, capsys):
    live = LearnedEstimator(tiny_models["gru"][0], design=baseline).streaming()
    with Device("delta6sim://stiff") as dev:
        with pytest.raises(Exception, match="trained for design delta6 .* the device runs stiff"):
            live.check_device(dev.info())
    assert main(["stream", "--port", "delta6sim://stiff", "--model",
                 str(tiny_models["gru"][0])]) == 2
    assert "the device runs stiff" in capsys.readouterr().err


def test_the_stream_command_shows_the_learned_wrench(tiny_models, capsys):
    assert main(["stream", "--port", "delta6sim://?motion=sine", "--model",
                 str(tiny_models["mlp"][0]), "--duration", "0.6", "--interval", "0.1"]) == 0
    captured = capsys.readouterr()
    lines = captured.out.strip().splitlines()
    assert len(lines) >= 3 and all(line.startswith("t ") and "nan" not in line for line in lines)
    assert "learned estimator: mlp, residual over the analytical model" in captured.err
    assert main(["stream", "--port", "delta6sim://", "--model", str(tiny_models["mlp"][0]),
                 "--rate", "200"]) == 2
    assert "trained on samples at 50 Hz" in capsys.readouterr().err


def test_a_graph_that_fails_to_run_is_one_line(tmp_path, tiny_models, baseline, unit_logs):
    # Right types and shapes on paper, but it runs only batches of a multiple of 7 windows.
    card = {p.key: p.value for p in onnx.load(str(tiny_models["mlp"][0])).metadata_props}
    path = graph_model(tmp_path / "one.onnx", card, reshape=[-1, 7, 6])
    est = LearnedEstimator(path, design=baseline)
    log = read_log(unit_logs[1])
    with pytest.raises(ModelFileError) as err:
        est.predict_arrays(log.t[:5], log.theta[:5])
    assert "one.onnx: the model fails to run" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("back", [0.0, 5.0])
def test_time_that_does_not_go_forward_starts_a_new_window(tiny_models, baseline, unit_logs,
                                                           back):
    # A device restart (or a new session) counts time afresh: the window before it is another
    # run's, in the batch and in the stream alike.
    log = read_log(unit_logs[1])
    t, theta = log.t[:200].copy(), log.theta[:200].copy()
    t[120:] -= t[120] - t[119] + back      # row 120 at or before row 119's time
    est = LearnedEstimator(tiny_models["mlp"][0], design=baseline)
    batch = est.predict_arrays(t, theta)
    fresh = est.predict_arrays(t[120:], theta[120:])
    assert np.allclose(batch[120:], fresh, rtol=0, atol=1e-9)
    live = est.streaming()
    stream = np.array([live.update(ti, row) for ti, row in zip(t, theta)])
    scale = np.nanmax(np.abs(batch), axis=0)
    assert np.nanmax(np.abs(stream - batch) / scale) < 1e-6


@pytest.mark.parametrize("cut", [30, 60, 61])
def test_a_new_device_session_starts_a_new_window(tiny_models, baseline, unit_logs, cut):
    # The session changes at row 60: inside the second block (cut 30), exactly at its start
    # (cut 60: the break falls on the window's first new row), or as the first block's last
    # row (cut 61).
    log = read_log(unit_logs[1])
    t, theta = log.t[:100], log.theta[:100]
    est = LearnedEstimator(tiny_models["mlp"][0], design=baseline)
    live = est.streaming()
    session = np.repeat([3, 4], [60, 40])       # the device restarted; its clock did not
    got = np.vstack([live.update_block(t[:cut], theta[:cut], session[:cut]),
                     live.update_block(t[cut:], theta[cut:], session[cut:])])
    assert np.allclose(got[60:], est.predict_arrays(t[60:], theta[60:]), rtol=0, atol=1e-9)
    assert np.allclose(got[:60], est.predict_arrays(t[:60], theta[:60]), rtol=0, atol=1e-9)
