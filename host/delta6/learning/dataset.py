"""A training set from a log: one window per row, the target the wrench less the base model's
(zero for an end-to-end model), standardised on the training rows only (numpy)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.diagnosis.data import MIN_JOINT_SPREAD_RAD, check_motion  # noqa: F401 (re-exported)
from delta6.learning.windows import WINDOW, Normalisation, time_split, windows

# check_motion (diagnosis.data): a joint whose angle spreads less than MIN_JOINT_SPREAD_RAD
# over a training log (standard deviation: about five encoder counts) shows a model nothing of
# how the wrench depends on it, and its standardisation would blow up any other log's angles.


@dataclass
class Dataset:
    window: int
    rate_hz: float
    norm: Normalisation
    inputs: np.ndarray      # (n, window, 6) float32, standardised
    targets: np.ndarray     # (n, 6) float32, standardised
    holdout: float
    wrench: np.ndarray      # (n, 6) the logged wrench of the rows kept
    base: np.ndarray        # (n, 6) the base model's wrench of the rows kept
    theta: np.ndarray       # (n, 6) the newest reading of the rows kept (rad)

    def __len__(self) -> int:
        return len(self.targets)

    def split(self, holdout: float | None = None) -> int:
        """First row of the held-out tail."""
        return time_split(len(self), self.holdout if holdout is None else holdout)


def build(t: np.ndarray, theta: np.ndarray, wrench: np.ndarray, base: np.ndarray, *,
          rate_hz: float, holdout: float, window: int = WINDOW) -> Dataset:
    """Rows whose window or target holds a NaN are left out; the normalisation is fitted on
    the rows before the held-out tail."""
    win = windows(theta, t, rate_hz, window)
    target = np.asarray(wrench, float) - np.asarray(base, float)
    keep = np.isfinite(win).all(axis=(1, 2)) & np.isfinite(target).all(axis=1)
    win, target = win[keep], target[keep]
    wrench, base = np.asarray(wrench, float)[keep], np.asarray(base, float)[keep]
    if len(target) < 20:
        raise ValueError(f"too few usable samples to train on: {len(target)}")
    split = time_split(len(target), holdout)
    norm = Normalisation.fit(win[:split], target[:split])
    return Dataset(window=window, rate_hz=rate_hz, norm=norm, inputs=norm.inputs(win),
                   targets=norm.targets(target), holdout=holdout, wrench=wrench, base=base,
                   theta=win[:, -1, :])
