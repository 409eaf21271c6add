"""``delta6 evaluate --model``: one Table V row per model file, the error plot, refusals."""
from __future__ import annotations

import json

import numpy as np

from delta6.cli import main
from delta6.core import accuracy
from delta6.core.model import wrench
from delta6.core.spec import full_scale
from delta6.learning import LearnedEstimator
from delta6.link.logfile import read_log


def test_rows_are_named_after_the_model_files(tmp_path, tiny_models, unit_logs, baseline, capsys):
    models = [str(tiny_models[k][0]) for k in ("mlp", "gru")]
    out, plot = tmp_path / "t.json", tmp_path / "e.png"
    assert main(["evaluate", str(unit_logs[1]), "--model", *models, "--json", str(out),
                 "--plot", str(plot)]) == 0
    result = json.loads(out.read_text())
    assert [r["estimator"] for r in result["rows"]] == ["analytical", "mlp", "gru"]
    log = read_log(unit_logs[1])
    fs = full_scale(baseline)
    gru = LearnedEstimator(models[1], design=baseline).predict(log)
    expected = accuracy.percentiles(gru, log.wrench, fs, (95, 99, 100))
    assert np.allclose(result["rows"][2]["p99_pct"], expected["p99"])
    assert np.allclose(result["rows"][2]["max_pct"], expected["p100"])
    analytical = accuracy.percentiles(wrench(baseline, log.theta), log.wrench, fs, (99,))
    assert np.allclose(result["rows"][0]["p99_pct"], analytical["p99"])
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b"\x89PNG"
    text = capsys.readouterr().out
    assert any(line.split()[:2] == ["gru", "p99"] for line in text.splitlines())


def test_bad_models_get_one_line_and_exit_2(tmp_path, tiny_models, unit_logs, capsys):
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"\x08\x01garbage")
    for argv, words in (
            (["--model", str(junk)], "not a readable ONNX model"),
            (["--model", str(tiny_models["mlp"][0]), "--design", "designs/stiff.toml"],
             "recorded with design delta6"),
            (["--model", str(tiny_models["mlp"][0]), str(tiny_models["mlp"][0])],
             "share a name")):
        assert main(["evaluate", str(unit_logs[1]), *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err, err


def test_a_plot_that_cannot_be_written_is_refused_in_one_line(tmp_path, capsys):
    log = tmp_path / "run.csv"
    assert main(["simulate", "--duration", "10", "-o", str(log)]) == 0
    for plot, words in ((tmp_path / "errors.txt", "not an image format"),
                        (tmp_path / "none" / "errors.png", "does not exist"),
                        (tmp_path, "is a folder")):
        capsys.readouterr()
        assert main(["evaluate", str(log), "--plot", str(plot)]) == 2, plot
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err, err
    assert main(["evaluate", str(log), "--plot", str(tmp_path / "errors.svg")]) == 0
    assert (tmp_path / "errors.svg").read_text().lstrip().startswith("<?xml")


def test_a_device_log_is_refused_where_a_reference_is_needed(tmp_path, capsys):
    # A device log's wrench is the board's own output: Table V against it, or a model trained
    # to reproduce it, would compare the model with itself.
    from delta6.link.logfile import LogWriter
    log = tmp_path / "device.csv"
    with LogWriter(log, {"design": "delta6", "wrench_source": "device"}) as w:
        w.write_block(np.arange(10) * 0.004, np.zeros((10, 6)), np.zeros((10, 6)))
    for argv in (["evaluate", str(log)],
                 ["train", str(log), "--model", "mlp", "-o", str(tmp_path / "m.onnx")],
                 ["train", str(log), "--target", "mcu", "-o", str(tmp_path / "m.json")]):
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "device's own model output" in err, (argv, err)


def test_a_log_partly_at_another_rate_gets_a_note(tmp_path, tiny_models, unit_logs, capsys):
    # Its median step is the model's; a third of it at half the rate is not (the window then
    # spans twice the time there).
    from delta6.link.logfile import open_log_writer
    log = read_log(unit_logs[1])
    t = log.t.copy()
    n = len(t) // 3
    t[-n:] = t[-n - 1] + 2 * (t[-n:] - t[-n - 1])
    mixed = tmp_path / "mixed.csv"
    with open_log_writer(mixed, {k: v for k, v in log.meta.items() if k != "schema"}) as w:
        w.write_block(t, log.theta, log.wrench)
    model = str(tiny_models["mlp"][0])
    for path, noted in ((unit_logs[1], False), (mixed, True)):
        capsys.readouterr()
        assert main(["evaluate", str(path), "--model", model]) == 0
        err = capsys.readouterr().err
        assert ("of the log's time steps are more than 25% away from its median step" in err) \
            == noted, err


def test_outputs_that_would_be_lost_are_refused_before_the_work(tmp_path, capsys):
    """A plot without a suffix (matplotlib wrote NAME.png, a file no check saw), --json and
    --plot on one file (the plot replaced the table), and a --json over a file of another
    kind (a twin's truth file); the command's own earlier table is replaced."""
    log = tmp_path / "run.csv"
    assert main(["simulate", "--duration", "10", "-o", str(log)]) == 0
    truth = tmp_path / "run.truth.json"
    kept = truth.read_bytes()
    for argv, words in (
            (["--plot", str(tmp_path / "noext")], "give the image format as its suffix"),
            (["--json", str(tmp_path / "p.png"), "--plot", str(tmp_path / "p.png")],
             "--json and --plot name the same file"),
            (["--json", str(truth)], "exists and is not a Table V of delta6 evaluate")):
        capsys.readouterr()
        assert main(["evaluate", str(log), *argv]) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.truth.json"]
    assert truth.read_bytes() == kept
    table = tmp_path / "t.json"
    for _ in range(2):      # a re-run over its own table
        assert main(["evaluate", str(log), "--json", str(table)]) == 0
    assert json.loads(table.read_text())["rows"][0]["estimator"] == "analytical"


def test_an_interrupted_evaluate_leaves_no_file_under_the_final_names(tmp_path, monkeypatch):
    import pathlib

    from matplotlib.figure import Figure
    log = tmp_path / "run.csv"
    assert main(["simulate", "--duration", "10", "-o", str(log)]) == 0
    plot, table = tmp_path / "e.png", tmp_path / "t.json"

    def savefig(self, fname, **kw):
        with open(fname, "wb") as f:
            f.write(b"\x89PNG half")
        raise KeyboardInterrupt

    monkeypatch.setattr(Figure, "savefig", savefig)
    assert main(["evaluate", str(log), "--plot", str(plot)]) == 130
    monkeypatch.undo()

    def write_text(self, text, *a, **kw):
        with open(self, "w") as f:
            f.write(text[:10])
        raise KeyboardInterrupt

    monkeypatch.setattr(pathlib.Path, "write_text", write_text)
    assert main(["evaluate", str(log), "--json", str(table)]) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.truth.json"]
