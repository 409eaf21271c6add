"""Small logs made from the analytical model, for diagnosis and command-line tests."""
from __future__ import annotations

import numpy as np

from delta6.core import model
from delta6.core.spec import full_scale
from delta6.link.logfile import LogData


def synthetic_log(design, kind, n=12000, seed=0):
    """A smooth multi-sine trajectory through the analytical model with one injected error
    (here only errors the model itself can express; the twin's tests cover the rest)."""
    rng = np.random.default_rng(seed)
    p = model.Params.from_design(design)
    t = np.arange(n) / 50.0
    theta = np.zeros((n, 6))
    for j in range(6):
        for f in rng.uniform(0.01, 0.4, 5):
            theta[:, j] += rng.uniform(0.03, 0.1) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6))
    enc = theta.copy()
    truth = p
    if kind == "stiffness_mismatch":
        truth = p.with_(k=p.k * np.array([1.05, 0.97, 1.02, 1.04, 0.96, 1.03]))
    elif kind == "encoder_offset":
        enc = theta + np.array([0.01, -0.008, 0.005, 0.01, -0.01, 0.006])
    w = model.wrench(truth, theta) + rng.normal(size=(n, 6)) * full_scale(design) * 1e-3
    enc = np.round(enc / model.ENCODER_COUNT_RAD) * model.ENCODER_COUNT_RAD
    return LogData(t=t, theta=enc, wrench=w)
