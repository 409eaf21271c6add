"""What a residual model is trained over: nothing (end-to-end), the analytical model, or the
unit's calibrated model (``delta6 calibrate``; the "hybrid").

A base gives the wrench for a whole log (``batch``) and, for the streaming estimator, a block of
samples at a time (``update_block``, the state carried from block to block; a sample is a block
of one); both must agree. The learned network adds what the base misses.
"""
from __future__ import annotations

import numpy as np

from delta6.core import model
from delta6.core.calibrated import CalibratedModel, counts_from_angles, periods_between
from delta6.core.calibration import Calibration
from delta6.core.design import Design


class NoBase:
    """End-to-end: the network predicts the whole wrench."""

    name = "none"

    def batch(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(theta), dtype=float)

    def update_block(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(theta), dtype=float)

    def reset(self) -> None:
        pass


class AnalyticalBase:
    """The paper's analytical model on the newest reading of the window (stateless)."""

    name = "analytical"

    def __init__(self, design: Design):
        self.params = model.Params.from_design(design)

    def batch(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return model.wrench(self.params, theta)

    def update_block(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return model.wrench(self.params, np.asarray(theta, float))

    def reset(self) -> None:
        pass


class CalibrationBase:
    """The calibrated model (causal, with a few numbers of state per joint) run over the
    samples in order at the model's rate (a block at a time, vectorised; the state carries
    over between blocks). A sample with a missing angle gives NaN and leaves the state
    as it was, in the batch and in the stream alike; a sample after missing ones (a gap in
    the samples' times) moves the history but is no speed, as the board does after a failed
    read. (A record the link lost is no gap on the board, which solved it: after one, the two
    differ for a few samples.)"""

    name = "calibration"

    def __init__(self, design: Design, calibration: Calibration, rate_hz: float):
        self.calibrated = CalibratedModel(design, calibration)
        self.calibration = calibration
        self.dt = 1.0 / rate_hz
        self.state = None
        self.last_t = None      # the time of the last sample the state ran through

    def batch(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return self._run(t, theta, None, None)[0]

    def update_block(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The state runs on from the last block through this block's complete rows."""
        out, self.state, self.last_t = self._run(t, theta, self.state, self.last_t)
        return out

    def _run(self, t, theta, state, last_t):
        theta = np.asarray(theta, dtype=float).reshape(-1, 6)
        t = np.asarray(t, dtype=float).reshape(-1)
        out = np.full(theta.shape, np.nan)
        ok = np.isfinite(theta).all(axis=1)
        if ok.any():
            periods = periods_between(t[ok], self.dt, last_t if state is not None else None)
            out[ok], state = self.calibrated.run(counts_from_angles(theta[ok]), self.dt, state,
                                                 periods)
            last_t = float(t[ok][-1])
        return out, state, last_t

    def reset(self) -> None:
        self.state = None
        self.last_t = None
