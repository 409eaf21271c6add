"""What a residual model is trained over: nothing (end-to-end), or the analytical model.

A base gives the wrench for a whole log (``batch``) and, for the streaming estimator, sample by
sample (``update``); both must agree exactly. The learned network adds what the base misses.
"""
from __future__ import annotations

import numpy as np

from delta6.core import model
from delta6.core.design import Design


class NoBase:
    """End-to-end: the network predicts the whole wrench."""

    name = "none"

    def batch(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(theta), dtype=float)

    def update(self, t: float, theta: np.ndarray) -> np.ndarray:
        return np.zeros(6)

    def reset(self) -> None:
        pass


class AnalyticalBase:
    """The paper's analytical model on the newest reading of the window (stateless)."""

    name = "analytical"

    def __init__(self, design: Design):
        self.params = model.Params.from_design(design)

    def batch(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return model.wrench(self.params, theta)

    def update(self, t: float, theta: np.ndarray) -> np.ndarray:
        return model.wrench(self.params, np.asarray(theta, float)[None])[0]

    def reset(self) -> None:
        pass
