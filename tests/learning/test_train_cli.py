"""``delta6 train`` on the command line: a model file with its summary, and one-line refusals."""
from __future__ import annotations

import subprocess
import sys

import onnx

from delta6.cli import main


def test_train_writes_a_model_and_prints_its_held_out_table(tmp_path, unit_logs, capsys):
    out = tmp_path / "m.onnx"
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--residual-over", "analytical",
                 "--epochs", "2", "--seed", "3", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "mlp, residual over the analytical model, design delta6 (0x535534af)" in captured.out
    assert "2 epochs" in captured.out and "ONNX equals torch within" in captured.out
    assert "p99 % FS" in captured.out and "analytical" in captured.out
    assert "epoch   2/2" in captured.err                   # the progress display
    props = {p.key: p.value for p in onnx.load(str(out)).metadata_props}
    assert props["delta6.base"] == "analytical" and '"seed": 3' in props["delta6.training"]


def test_bad_requests_get_one_line(tmp_path, unit_logs, capsys):
    log = str(unit_logs[0])
    cases = [
        (["train", log, "--model", "mlp", "--residual-over", "nothing", "-o", "x.onnx"],
         "--residual-over nothing"),
        (["train", str(tmp_path / "none.csv"), "--model", "mlp", "-o", "x.onnx"], "no such file"),
        (["train", log, "--model", "mlp", "--design", "designs/half-scale.toml", "-o", "x.onnx"],
         "recorded with design delta6"),
        (["train", log, "--model", "gru", "-o", str(tmp_path / "no" / "dir.onnx"), "--epochs",
          "1"], "does not exist"),
    ]
    for argv, words in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err


def test_without_torch_training_says_how_to_get_it(tmp_path, unit_logs):
    code = ("import sys; sys.modules['torch'] = None\n"      # as if the extra were missing
            "from delta6.cli import main\n"
            f"sys.exit(main(['train', {str(unit_logs[0])!r}, '--model', 'mlp', '-o', "
            f"{str(tmp_path / 'm.onnx')!r}]))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 2
    err = out.stderr.strip()
    assert "training needs torch" in err and "delta6[train]" in err and "\n" not in err
