"""Small twin runs and briefly trained models shared by the learning tests."""
from __future__ import annotations

import pytest

from delta6 import twin
from delta6.core.design import load
from delta6.core.paths import DEFAULT_DESIGN

#: Seconds of the small calibration and evaluation runs (50 Hz).
TRAIN_S = 150
EVAL_S = 60


@pytest.fixture(scope="session")
def design():
    return load(DEFAULT_DESIGN)


@pytest.fixture(scope="session")
def unit_logs(tmp_path_factory, design):
    """A calibration run of one simulated unit (the paper scenario) and a second run of the same
    unit (its effects, a new trajectory and noise), as logs."""
    folder = tmp_path_factory.mktemp("unit")
    first = twin.simulate(design, twin.scenario_effects("paper", seed=1), duration_s=TRAIN_S,
                          seed=1, scenario="paper")
    again = twin.simulate(design, twin.effects_from_truth(first.truth), duration_s=EVAL_S,
                          seed=2, scenario="paper")
    return (twin.write_log(first, folder / "train.csv")[0],
            twin.write_log(again, folder / "eval.csv")[0])


@pytest.fixture(scope="session")
def tiny_models(tmp_path_factory, design, unit_logs):
    """One briefly trained, exported model of each kind (the MLP over the analytical model),
    with what training produced: {kind: (path, fitted)}."""
    from delta6.learning import fit
    from delta6.learning.presets import KINDS, preset
    from delta6.link.logfile import read_log

    folder = tmp_path_factory.mktemp("models")
    log = read_log(unit_logs[0])
    out = {}
    for kind in KINDS:
        chosen = preset("default", kind).with_recipe(max_epochs=1, epoch_fraction=0.3)
        base = "analytical" if kind == "mlp" else "none"
        fitted = fit.fit(log, design, chosen, base=base, seed=3, threads=1)
        path = folder / f"{kind}.onnx"
        fit.write(fitted, path)
        out[kind] = (path, fitted)
    return out
