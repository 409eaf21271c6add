"""Small twin runs and briefly trained models for the learning tests (fixtures ``unit_logs``
and ``tiny_models`` in tests/conftest.py)."""
from __future__ import annotations

from pathlib import Path

from delta6 import twin

#: Seconds of the small calibration and evaluation runs (50 Hz).
TRAIN_S = 150
EVAL_S = 60


def unit_logs(design, folder: Path) -> tuple[Path, Path]:
    """A calibration run of one simulated unit (the paper scenario) and a second run of the same
    unit (its effects, a new trajectory and noise), as logs."""
    first = twin.simulate(design, twin.scenario_effects("paper", seed=1), duration_s=TRAIN_S,
                          seed=1, scenario="paper")
    again = twin.simulate(design, twin.effects_from_truth(first.truth), duration_s=EVAL_S,
                          seed=2, scenario="paper")
    return (twin.write_log(first, folder / "train.csv")[0],
            twin.write_log(again, folder / "eval.csv")[0])


def tiny_models(design, train_log: Path, folder: Path) -> dict:
    """One briefly trained, exported model of each kind (the MLP over the analytical model),
    with what training produced: {kind: (path, fitted)}."""
    from delta6.learning import fit
    from delta6.learning.presets import KINDS, preset
    from delta6.link.logfile import read_log

    log = read_log(train_log)
    out = {}
    for kind in KINDS:
        chosen = preset("default", kind).with_recipe(max_epochs=1, epoch_fraction=0.3)
        base = "analytical" if kind == "mlp" else "none"
        fitted = fit.fit(log, design, chosen, base=base, seed=3)
        path = folder / f"{kind}.onnx"
        fit.write(fitted, path)
        out[kind] = (path, fitted)
    return out
