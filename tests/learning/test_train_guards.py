"""What ``delta6 train`` refuses or says before and after the work: a joint that never moves,
options of the other target, a host model the on-chip export would replace, and the analytical
model beside an end-to-end model's held-out table."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6.cli import main
from delta6.core import calibration as calibration_mod
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.learning import LearnedEstimator
from delta6.learning.card import ModelFileError
from delta6.learning.dataset import MIN_JOINT_SPREAD_RAD, check_motion
from delta6.learning.windows import Normalisation
from delta6.link.logfile import open_log_writer, read_log

from support.calibrations import history_calibration


def _with_still_joint(source, out, joint: int):
    log = read_log(source)
    theta = log.theta.copy()
    theta[:, joint] = theta[0, joint]
    with open_log_writer(out, {k: v for k, v in log.meta.items() if k != "schema"}) as w:
        w.write_block(log.t, theta, log.wrench)
    return out


def test_a_joint_that_never_moves_is_refused_by_both_targets(tmp_path, unit_logs, capsys):
    """Its standardisation would divide by the rounding error of its mean: any other log's
    angle of that joint then reaches the network at 1e13 standard deviations."""
    still = _with_still_joint(unit_logs[0], tmp_path / "still.csv", 3)
    for options in (["--model", "mlp", "-o", str(tmp_path / "m.onnx")],
                    ["--target", "mcu", "-o", str(tmp_path / "m.json")]):
        capsys.readouterr()
        assert main(["train", str(still), "--epochs", "1", "--quiet", *options]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "theta_e4 hardly moves" in err, err
    assert not (tmp_path / "m.onnx").exists() and not (tmp_path / "m.json").exists()


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-0.4, 0.4), min_size=6, max_size=6),
       st.lists(st.floats(0.0, 0.2), min_size=6, max_size=6))
def test_check_motion_names_exactly_the_joints_under_the_spread(centre, spread):
    rng = np.random.default_rng(0)
    theta = np.asarray(centre) + rng.standard_normal((400, 6)) * np.asarray(spread)
    still = [j for j in range(6) if theta[:, j].std() < MIN_JOINT_SPREAD_RAD]
    if not still:
        check_motion(theta)
        return
    with pytest.raises(UserError) as err:
        check_motion(theta)
    named = [j for j in range(6) if f"theta_e{j + 1}" in str(err.value)]
    assert named == still


def test_a_column_without_spread_keeps_scale_one():
    win = np.zeros((50, 25, 6))
    win[..., 0] = np.linspace(0, 1, 50)[:, None]
    win[..., 3] = 0.1 + 1e-17 * np.arange(25)         # rounding noise, not motion
    norm = Normalisation.fit(win, np.ones((50, 6)))
    assert norm.theta_scale[3] == 1.0 and norm.delta_scale[3] == 1.0
    assert norm.theta_scale[0] > 0.1


def test_options_of_the_other_target_are_refused(tmp_path, unit_logs, capsys):
    log = str(unit_logs[0])
    cases = [
        (["--model", "mlp", "--hidden", "16", "-o", str(tmp_path / "a.onnx")], "--hidden"),
        (["--model", "mlp", "--name", "foo", "-o", str(tmp_path / "a.onnx")], "--name"),
        (["--target", "mcu", "--preset", "paper", "-o", str(tmp_path / "a.json")], "--preset"),
        (["--target", "mcu", "--max-minutes", "1", "-o", str(tmp_path / "a.json")],
         "--max-minutes"),
        (["--target", "mcu", "--threads", "2", "-o", str(tmp_path / "a.json")], "--threads"),
        # ... also when the value is the host's default: it would be ignored all the same.
        (["--target", "mcu", "--preset", "default", "-o", str(tmp_path / "a.json")],
         "--preset"),
        (["--target", "mcu", "--threads", "1", "-o", str(tmp_path / "a.json")], "--threads"),
        (["--target", "mcu", "--model", "mlp", "-o", str(tmp_path / "a.json")], "--model"),
    ]
    for options, words in cases:
        capsys.readouterr()
        assert main(["train", log, "--epochs", "1", "--quiet", *options]) == 2, options
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err and "only for" in err, err


def test_the_on_chip_export_never_replaces_a_host_model(tmp_path, tiny_models, unit_logs,
                                                        capsys):
    host_model, _ = tiny_models["mlp"]
    kept = tmp_path / "unit.onnx"
    kept.write_bytes(host_model.read_bytes())
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--epochs", "1", "--quiet",
                 "-o", str(tmp_path / "unit.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not an on-chip model's" in err, err
    assert kept.read_bytes() == host_model.read_bytes()
    assert not (tmp_path / "unit.json").exists()


def test_on_chip_files_on_host_paths_say_what_they_are(tmp_path, unit_logs, capsys):
    model = tmp_path / "chip.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--epochs", "1", "--quiet",
                 "-o", str(model)]) == 0
    # Its float network is no host estimator; its JSON runs in evaluate, not in a host session.
    capsys.readouterr()
    assert main(["evaluate", str(unit_logs[1]), "--model", str(model.with_suffix(".onnx"))]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "float network of on-chip model 'chip'" in err, err
    with pytest.raises(ModelFileError, match="an on-chip model file"):
        LearnedEstimator(model, design=load("designs/delta6.toml"))
    # Beside a calibration, a model over the analytical model is scored over its own base.
    cal = calibration_mod.save(history_calibration(load("designs/delta6.toml"), "unit"),
                               tmp_path / "cal.toml")
    capsys.readouterr()
    assert main(["evaluate", str(unit_logs[1]), "--calibration", str(cal), "--model",
                 str(model), "--json", str(tmp_path / "t.json")]) == 0
    rows = {r["estimator"]: r for r in json.loads((tmp_path / "t.json").read_text())["rows"]}
    assert {"analytical", "chip"} <= set(rows)
    alone = tmp_path / "alone.json"
    assert main(["evaluate", str(unit_logs[1]), "--model", str(model), "--json",
                 str(alone)]) == 0
    rows_alone = {r["estimator"]: r for r in json.loads(alone.read_text())["rows"]}
    assert rows_alone["chip"]["p99_pct"] == rows["chip"]["p99_pct"]


def test_an_end_to_end_summary_shows_the_analytical_model(tmp_path, unit_logs, capsys):
    out = tmp_path / "e2e.onnx"
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--epochs", "1", "--quiet",
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "analytical" in text
    # One epoch of an end-to-end network is far from the physics: the summary says so.
    assert "worse than the analytical model" in text


def _named_runs(tmp_path, capsys, name):
    """The error line of train --target mcu and of calibrate given ``--name NAME`` and a log
    that does not exist (each must end with status 2 either way)."""
    log = str(tmp_path / "none.csv")
    for argv in (["train", log, "--target", "mcu", "--name", name, "-o",
                  str(tmp_path / "m.json")],
                 ["calibrate", log, "--name", name, "-o", str(tmp_path / "c.toml")]):
        capsys.readouterr()
        assert main(argv) == 2, argv
        yield capsys.readouterr().err.strip()


@pytest.mark.parametrize("name", ["", "   ", "x" * 24, "caf\u00e9", "tab\there", "new\nline",
                                  " lead", "trail "])
def test_a_name_that_is_no_printable_label_is_refused_before_the_work(tmp_path, capsys, name):
    # Calibration and model names are labels (design.label_problem): printable ASCII that
    # fits the device-info record; refused before the log is read.
    for err in _named_runs(tmp_path, capsys, name):
        assert len(err.splitlines()) == 1 and "--name" in err and "must be" in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["unit 7 (bench)", 'a"b\\c??/d e', "../../../../q"])
def test_a_printable_label_passes_the_name_check(tmp_path, capsys, name):
    # Yesterday's files were named so (calibrate -o "unit 7.toml" by default): the name is
    # accepted and the command goes on to the log, which is missing.
    for err in _named_runs(tmp_path, capsys, name):
        assert "--name" not in err and "none.csv" in err, err


def test_the_default_name_hint_says_what_the_default_is(tmp_path, capsys):
    log = str(tmp_path / "none.csv")
    # Both commands cut their default to the limit: a long -o names the model or the
    # calibration fine (the command goes on to the missing log), a blank one does not.
    long = "x" * 30
    assert main(["train", log, "--target", "mcu", "-o", str(tmp_path / f"{long}.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--name" not in err and "none.csv" in err, err
    assert main(["train", log, "--target", "mcu", "-o", str(tmp_path / " .json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--name" in err and "-o's file name without its extension, cut to 23" in err, err
    assert main(["calibrate", log, "-o", str(tmp_path / " .toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--name" in err and "-o's file name without .toml, cut to 23" in err, err


def test_a_host_model_is_written_only_as_onnx(tmp_path, unit_logs, capsys):
    out = tmp_path / "model.json"
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--epochs", "1", "--quiet",
                 "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "MODEL.onnx" in err and "epoch" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("target", [["--model", "mlp", "-o", "m.onnx"],
                                    ["--target", "mcu", "-o", "m.json"]])
def test_a_seed_beyond_what_torch_takes_is_one_line(tmp_path, unit_logs, capsys, target):
    """torch.manual_seed ended in an overflow traceback; the parser bounds the seed."""
    argv = ["train", str(unit_logs[0]), "--seed", "99999999999999999999", "--quiet",
            *target[:-1], str(tmp_path / target[-1])]
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err                     # a usage error is one line too
    assert "--seed must be at most 4294967295, got 99999999999999999999" in err[0], err
    assert "Traceback" not in "\n".join(err) and list(tmp_path.iterdir()) == []


def test_train_replaces_only_a_model_of_its_own_kind(tmp_path, unit_logs, capsys):
    """A twin's truth file, or any other file under -o, is refused before the work; a file
    of the kind the target writes is replaced (a re-run)."""
    truth = tmp_path / "run.truth.json"
    truth.write_text('{"schema": "delta6-twin-truth/1"}\n')
    notes = tmp_path / "notes.onnx"
    notes.write_text("not a model\n")
    for argv, path in ((["--target", "mcu", "-o", str(truth)], truth),
                       (["--model", "mlp", "-o", str(notes)], notes)):
        before = path.read_bytes()
        capsys.readouterr()
        assert main(["train", str(unit_logs[0]), "--epochs", "1", "--quiet", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "exists and is not" in err, err
        assert "epoch" not in err and path.read_bytes() == before
    assert not truth.with_suffix(".onnx").exists()
    chip = tmp_path / "chip.json"
    for _ in range(2):
        assert main(["train", str(unit_logs[0]), "--target", "mcu", "--epochs", "1", "--quiet",
                     "-o", str(chip)]) == 0
    # An on-chip model's float network is no host model: host training does not replace it.
    capsys.readouterr()
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--epochs", "1", "--quiet",
                 "-o", str(chip.with_suffix(".onnx"))]) == 2
    assert "is not a host model" in capsys.readouterr().err


def test_an_interrupted_on_chip_export_keeps_the_earlier_pair(tmp_path, unit_logs,
                                                              monkeypatch):
    """A signal after the ONNX is written, before the JSON: the earlier JSON and ONNX stay
    as they were (no new ONNX beside an old JSON), and no temporary file is left."""
    from delta6.core import residualmodel
    model = tmp_path / "chip.json"
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--epochs", "1", "--quiet",
                 "-o", str(model)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert sorted(before) == ["chip.json", "chip.onnx"]

    seen = []

    def dumps(_model):
        seen.extend(p.name for p in tmp_path.iterdir())
        raise KeyboardInterrupt

    monkeypatch.setattr(residualmodel, "dumps", dumps)
    assert main(["train", str(unit_logs[0]), "--target", "mcu", "--epochs", "1", "--quiet",
                 "--seed", "5", "-o", str(model)]) == 130
    assert any(n.startswith("chip.onnx.") and n.endswith(".partial") for n in seen), seen
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_a_refused_export_keeps_the_earlier_model(tmp_path, tiny_models, unit_logs, capsys,
                                                  monkeypatch):
    """An export that differs from the trained network is refused: it used to replace the
    earlier model first and then delete it; it is now checked under a temporary name."""
    from delta6.learning import fit as fit_mod
    host_model, _ = tiny_models["mlp"]
    kept = tmp_path / "unit.onnx"
    kept.write_bytes(host_model.read_bytes())
    monkeypatch.setattr(fit_mod.export_mod, "max_difference", lambda *args: 1.0)
    assert main(["train", str(unit_logs[0]), "--model", "mlp", "--epochs", "1", "--quiet",
                 "-o", str(kept)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "differs from the trained one" in err, err
    assert kept.read_bytes() == host_model.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["unit.onnx"]
