"""A unit's calibration and an on-chip residual model over it, as files, without training: what
a firmware image carries when both are built in (flash and board tests)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from delta6.core import calibration as C
from delta6.core import int8net, int8quant, residualmodel
from delta6.learning import mcu

from support.calibrations import random_calibration
from support.int8nets import trained_like


def calibration_and_model(design, folder: Path, seed: int = 3, name: str = "onchip"):
    """(calibration, its path, model, its path): a random calibration of ``design`` and a
    randomly weighted residual network over it (the default over a calibration), quantized
    on random feature values."""
    cal = random_calibration(design, seed)
    cal_path = C.save(cal, Path(folder) / "unit.toml")
    rng = np.random.default_rng(seed)
    scale = mcu.input_scale_for(design)
    counts = rng.integers(0, 16384, (300, 6))
    v = int8net.feature_values(mcu.CALIBRATED_FEATURES,
                               int8net.quantize_input(rng.normal(0, 5, (300, 6)), scale), counts)
    # The default over a calibration: a linear map (what codegen takes at the rated rate).
    float_net, _ = trained_like(rng, mcu.CALIBRATED_FEATURES, v.astype(float),
                                hidden=mcu.CALIBRATED_HIDDEN, rate_hz=100.0)
    net = int8quant.quantize(dataclasses.replace(float_net, input_scale=scale), v.astype(float))
    model = residualmodel.ResidualModel(
        name=name, design_name=design.name, design_hash=design.hash32(), base="calibrated",
        net=net, calibration_name=cal.name, calibration_hash=cal.hash32())
    return cal, cal_path, model, residualmodel.save(model, Path(folder) / f"{name}.json")
