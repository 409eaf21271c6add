"""Windows of encoder readings and their standardisation (numpy only: training and inference
share it).

A model sees the newest reading and the ``window - 1`` before it. Rows whose history is shorter
(the start of a log, or after a gap in time: lost samples) repeat the oldest reading they have,
as if the device had been standing still before it; the streaming estimator does the same, so
that a log evaluated at once and sample by sample give the same wrenches.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass

import numpy as np

#: The paper's window length T_w (Section V.B).
WINDOW = 25
#: A step between two samples longer than this many nominal periods starts a new segment.
GAP_PERIODS = 1.5


def nominal_rate(t: np.ndarray) -> float:
    """Sample rate of a log, Hz: the reciprocal of its median time step."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        raise ValueError("a rate needs at least two samples")
    return float(1.0 / np.median(np.diff(t)))


#: A step this far (either way) from a log's median step is at another rate, not jitter.
OFF_RATE = 0.25
#: A log with more of its steps off its median rate than this gets a note from the commands
#: that score a model on it (the window, or an on-chip model's stride, assumes one rate).
OFF_RATE_SHARE = 0.1


def off_rate_share(t: np.ndarray) -> float:
    """Share of a log's time steps more than ``OFF_RATE`` away from its median step (where
    :func:`nominal_rate` comes from): a mixed-rate log, or one that lost many samples."""
    steps = np.diff(np.asarray(t, dtype=float))
    if len(steps) == 0:
        return 0.0
    ratio = steps / np.median(steps)
    return float(np.mean((ratio < 1 - OFF_RATE) | (ratio > 1 + OFF_RATE)))


def new_segment(step, rate_hz: float) -> np.ndarray:
    """Whether a time step (s) between two samples begins a new segment: longer than
    ``GAP_PERIODS`` periods (lost samples), or not forward at all (a device restart or a new
    session counts its time afresh)."""
    step = np.asarray(step, dtype=float)
    return ~((step > 0) & (step <= GAP_PERIODS / rate_hz))


def segment_starts(t: np.ndarray, rate_hz: float) -> np.ndarray:
    """Index of the first row of each row's contiguous segment, (n,) int (:func:`new_segment`)."""
    t = np.asarray(t, dtype=float)
    brk = np.ones(len(t), dtype=bool)
    brk[1:] = new_segment(np.diff(t), rate_hz)
    return np.maximum.accumulate(np.where(brk, np.arange(len(t)), 0))


def window_index(starts: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """(n, window) row indices of each row's window, oldest first, newest (the row) last;
    indices before the segment start are clamped to it."""
    rows = np.arange(len(starts))
    idx = rows[:, None] + np.arange(1 - window, 1)[None, :]
    return np.maximum(idx, np.asarray(starts)[:, None])


def windows(theta: np.ndarray, t: np.ndarray, rate_hz: float, window: int = WINDOW) -> np.ndarray:
    """(n, window, 6) windows of ``theta`` ((n, 6)), one per row."""
    return np.asarray(theta, dtype=float)[window_index(segment_starts(t, rate_hz), window)]


@dataclass(frozen=True)
class Normalisation:
    """How windows and wrenches are standardised (the paper's "all inputs and outputs are first
    standardized").

    The newest reading of a window is standardised against the training mean and spread of
    the angles; each older reading enters as its difference from the newest, standardised
    against the spread of those differences. It is the same information as the raw window (a
    fixed invertible linear map of it), but the motion within the window, a few encoder counts
    between samples, reaches the network at order one instead of a thousandth of the angle
    spread. The target (the wrench, or what the base model leaves of it) is standardised per
    axis.
    """

    theta_mean: tuple[float, ...]
    theta_scale: tuple[float, ...]
    delta_scale: tuple[float, ...]
    target_mean: tuple[float, ...]
    target_scale: tuple[float, ...]

    @classmethod
    def fit(cls, win: np.ndarray, target: np.ndarray) -> "Normalisation":
        """From training windows (n, w, 6) and targets (n, 6)."""
        newest = win[:, -1, :]
        delta = (win[:, :-1, :] - newest[:, None, :]).reshape(-1, win.shape[-1])
        return cls(theta_mean=_tup(newest.mean(0)), theta_scale=_tup(_spread(newest)),
                   delta_scale=_tup(_spread(delta)), target_mean=_tup(target.mean(0)),
                   target_scale=_tup(_spread(target)))

    def inputs(self, win: np.ndarray) -> np.ndarray:
        """Windows (n, w, 6) in rad -> network inputs (n, w, 6) float32."""
        win = np.asarray(win, dtype=float)
        newest = win[:, -1:, :]
        out = (win - newest) / np.asarray(self.delta_scale)
        out[:, -1:, :] = (newest - np.asarray(self.theta_mean)) / np.asarray(self.theta_scale)
        return out.astype(np.float32)

    def targets(self, y: np.ndarray) -> np.ndarray:
        return ((np.asarray(y, float) - self.target_mean) / np.asarray(self.target_scale)
                ).astype(np.float32)

    def wrench(self, z: np.ndarray) -> np.ndarray:
        """Network outputs (n, 6) back to physical units."""
        return np.asarray(z, dtype=float) * np.asarray(self.target_scale) + self.target_mean

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> "Normalisation":
        raw = json.loads(text)
        values = {k: tuple(float(v) for v in raw[k]) for k in cls.__dataclass_fields__}
        for k, v in values.items():
            if len(v) != 6 or not all(np.isfinite(v)):
                raise ValueError(f"{k} must be six finite numbers")
            if k.endswith("scale") and not all(NO_SPREAD <= x <= MAX_MAGNITUDE for x in v):
                # a fit never writes a spread under NO_SPREAD (it keeps 1 there)
                raise ValueError(f"{k} must lie in {NO_SPREAD:g}..{MAX_MAGNITUDE:g}")
            if not all(abs(x) <= MAX_MAGNITUDE for x in v):
                raise ValueError(f"{k} must lie in -{MAX_MAGNITUDE:g}..{MAX_MAGNITUDE:g}")
        return cls(**values)


#: A spread below this is rounding, not motion (rad, N, N*m): such a column keeps scale 1.
NO_SPREAD = 1e-9
#: Largest mean or spread a file may give (rad, N, N*m): beyond it the numbers are not a
#: sensor's (they would overflow the tables, or divide the angles to nothing).
MAX_MAGNITUDE = 1e6


def _spread(x: np.ndarray) -> np.ndarray:
    """Standard deviation per column, never (numerically) zero: a column that never changed
    keeps scale 1 instead of dividing by the rounding error of its mean."""
    sd = np.asarray(x, dtype=float).std(axis=0)
    return np.where(sd > NO_SPREAD, sd, 1.0)


def _tup(a) -> tuple[float, ...]:
    return tuple(float(v) for v in a)


def time_split(n: int, holdout: float) -> int:
    """First row of the held-out tail of ``n`` time-ordered rows (at least one row each side)."""
    if not 0 < holdout < 1:
        raise ValueError("the held-out fraction must be between 0 and 1")
    return int(min(max(round(n * (1 - holdout)), 1), n - 1))
