"""The ladder: the present effects added one by one, never making the held-out error worse.

Each step refits all added terms. A step that would raise the held-out p99 of an axis above
the step before (a flexible term that helps most axes but extrapolates on one) is damped on
that axis: the axis's prediction is blended with the step before, (1 - a_k) * before + a_k *
refit, with the largest a_k in 1, 0.9, ..., 0 that leaves the axis no worse. The p99 of an
axis depends on that axis's prediction alone, so each axis is settled by itself, and a_k = 0
is the step before exactly: no step is worse than its predecessor on any axis, not even by
the rounding of a p99.

Why per axis: the effect's parameters are shared by the six axes, and one blend weight for
all of them had to choose between two wrongs. An axis at its noise floor moves by a hair
either way under any correction, at first order in the weight: a strict common weight gave up
whole steps over such hairs (on a development run, 0.003 % FS on an axis at 0.18 % FS damped
every step of a ladder entirely), and a tolerance for them let real trade-offs through (under
one-axis pushes, a step taking one axis up by 2 % of its value while taking others down by
ten times that). Per axis, the compensation of an axis uses the step where it helps that
axis and leaves the axis alone where it does not; the step's parameters are its refit's.
"""
from __future__ import annotations

import numpy as np

ALPHAS = np.linspace(1.0, 0.0, 11)


def p99(err_pct: np.ndarray) -> np.ndarray:
    return np.percentile(np.abs(err_pct), 99, axis=0)


def p99_of_difference(y: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """p99 of |100 (y - pred)| per column, with one temporary array (long logs)."""
    tmp = np.subtract(y, pred)
    tmp *= 100.0
    np.abs(tmp, out=tmp)
    return np.percentile(tmp, 99, axis=0, overwrite_input=True)


def baseline_p99(y: np.ndarray) -> np.ndarray:
    """The analytical model's p99 (% FS) of the FS-normalised residual ``y``, rounded exactly
    as every step's (a step that leaves an axis alone reports the same number)."""
    return p99_of_difference(y, np.zeros((1, y.shape[1])))


def squared_error(y: np.ndarray, pred: np.ndarray) -> float:
    """Sum of (y - pred)^2 over all samples and axes, with one temporary array."""
    tmp = np.subtract(y, pred)
    np.square(tmp, out=tmp)
    return float(tmp.sum())


def monotone(y: np.ndarray, preds) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray,
                                             list[float], list[np.ndarray]]:
    """``y`` (n, 6) FS-normalised residual, ``preds`` the held-out predictions of the refit
    after each step (any iterable: a generator lets each be freed once used). Returns the
    per-axis blend weights of each step (6,), the held-out p99 (% FS) after each step, the
    final blended prediction (only one (n, 6) array is kept: long logs), the held-out
    squared error after each step, and the held-out p99 of each step's refit undamped (what
    one set of parameters, the step's refit, gives: the per-axis blend mixes refits). The
    steps start from :func:`baseline_p99`."""
    weights, p99s, sses, refits = [], [], [], []
    before = np.zeros_like(y)
    before_p99 = baseline_p99(y)
    for pred in preds:
        a = np.zeros(y.shape[1])
        after_p99 = before_p99.copy()
        refit = np.empty(y.shape[1])
        # One axis at a time (the p99 of an axis is its own): a long log's trials take
        # arrays of one column, not of six.
        for j in range(y.shape[1]):
            y_j, before_j, pred_j = y[:, j], before[:, j], pred[:, j]
            refit[j] = p99_of_difference(y_j, pred_j)
            step = np.subtract(pred_j, before_j, dtype=float)      # pred - before
            for alpha in ALPHAS[ALPHAS > 0]:
                trial_p99 = p99_of_difference(y_j, before_j + alpha * step)
                if trial_p99 <= before_p99[j]:
                    a[j] = alpha
                    after_p99[j] = trial_p99
                    break
            # An axis the step does not take keeps the step before exactly.
            if a[j] > 0:
                before_j += a[j] * step                             # a view: into ``before``
            del step
        refits.append(refit)
        weights.append(a)
        p99s.append(after_p99)
        sses.append(squared_error(y, before))
        before_p99 = after_p99
    return weights, p99s, before, sses, refits
