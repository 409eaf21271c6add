"""From a calibration log to a model file: the dataset, training, the held-out summary and the
ONNX export with its model card (needs torch: the ``train`` extra)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from delta6.core import accuracy
from delta6.core.calibration import Calibration, check_log_meta
from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.outputs import written_together
from delta6.core.spec import full_scale
from delta6.learning import dataset as dataset_mod
from delta6.learning import export as export_mod
from delta6.learning import nets, training
from delta6.learning.bases import AnalyticalBase, CalibrationBase, NoBase
from delta6.learning.card import ModelCard
from delta6.learning.presets import Preset
from delta6.learning.windows import WINDOW, nominal_rate
from delta6.link.logfile import LogData

#: Fewer samples than this cannot give a held-out tail worth stopping on.
MIN_SAMPLES = 500
#: Largest |onnxruntime - torch| accepted on the held-out windows (standardised units).
EXPORT_TOLERANCE = 1e-4


@dataclass
class Fitted:
    trained: training.Trained
    data: dataset_mod.Dataset
    card: ModelCard


def check_log(log: LogData, design: Design, calibration: Calibration | None, source: str
              ) -> None:
    check_log_meta(log.meta, design, calibration, source=source)
    if len(log.t) < MIN_SAMPLES:
        raise UserError(f"{source}: too few samples to train on ({len(log.t)}; at least "
                        f"{MIN_SAMPLES})")
    dataset_mod.check_motion(log.theta, source)


def base_model(name: str, design: Design, calibration: Calibration | None, rate_hz: float):
    if name == "none":
        return NoBase()
    if name == "analytical":
        return AnalyticalBase(design)
    if name == "calibration" and calibration is not None:
        return CalibrationBase(design, calibration, rate_hz)
    raise ValueError(f"unknown base {name!r} (a calibration base needs the calibration)")


def fit(log: LogData, design: Design, preset: Preset, *, base: str = "none",
        calibration: Calibration | None = None, seed: int = 0,
        threads: int = training.DEFAULT_THREADS, source: str = "the log",
        progress: Callable[[training.EpochReport], None] | None = None) -> Fitted:
    """Train ``preset`` on ``log``; ``base``: "none" (end-to-end), "analytical", or
    "calibration" (a residual over ``calibration``, the hybrid)."""
    check_log(log, design, calibration if base == "calibration" else None, source)
    rate = nominal_rate(log.t)
    base_est = base_model(base, design, calibration, rate)
    data = dataset_mod.build(log.t, log.theta, log.wrench, base_est.batch(log.t, log.theta),
                             rate_hz=rate, holdout=preset.recipe.holdout, window=WINDOW)
    trained = training.train(data, preset, seed=seed, threads=threads, progress=progress)
    split = data.split()
    fs = full_scale(design)
    held = data.norm.wrench(training.predict(trained.module, data.inputs[split:]))
    held += data.base[split:]
    best = trained.best
    summary = {
        "log": Path(source).name, "samples": len(log.t),
        "duration_s": round(float(log.t[-1] - log.t[0]), 3), "rate_hz": round(rate, 6),
        "seed": seed, "epochs": len(trained.history), "best_epoch": best.epoch,
        "stopped": trained.stopped, "holdout_mse": best.holdout_loss,
        "seconds": round(trained.seconds, 1), "parameters": nets.parameter_count(trained.module),
        "torch": torch.__version__, "threads": torch.get_num_threads(),
        "holdout_rows": len(data) - split,
        "holdout_pct_fs": _table(held, data.wrench[split:], fs),
        "holdout_base_pct_fs": _table(data.base[split:], data.wrench[split:], fs)
        if base != "none" else None,
        # What the model has to beat to be worth using (the base of a residual is shown above).
        "holdout_analytical_pct_fs": _table(AnalyticalBase(design).batch(None, data.theta[split:]),
                                            data.wrench[split:], fs),
    }
    card = ModelCard(kind=preset.net.kind, design_name=design.name, design_hash=design.hash32(),
                     base=base, window=data.window, rate_hz=rate, norm=data.norm,
                     calibration_name=calibration.name if base == "calibration" else "",
                     calibration_hash=calibration.hash32() if base == "calibration" else None,
                     hyperparameters=preset.as_dict(), training=summary)
    return Fitted(trained, data, card)


def write(fitted: Fitted, path: str | Path) -> float:
    """Export; returns the largest |onnxruntime - torch| on the held-out windows, refused above
    :data:`EXPORT_TOLERANCE`. Checked under a temporary name: a refused export leaves the file
    that was at ``path`` as it was."""
    with written_together(path) as (tmp,):
        export_mod.export(fitted.trained.module, fitted.card, tmp)
        split = fitted.data.split()
        diff = export_mod.max_difference(fitted.trained.module, tmp, fitted.data.inputs[split:])
        if not diff <= EXPORT_TOLERANCE:
            raise UserError(f"the exported model differs from the trained one by {diff:.3g} "
                            "(standardised units): not written")
    return diff


def _table(estimate: np.ndarray, reference: np.ndarray, fs: np.ndarray) -> dict:
    t = accuracy.percentiles(estimate, reference, fs, (95, 99, 100))
    return {k: [round(v, 4) for v in row] for k, row in t.items()}
