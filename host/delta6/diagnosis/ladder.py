"""The ladder: the present effects added one by one, never making the held-out error worse.

Each step refits all added terms. A step that would raise the held-out p99 of any axis above
the step before (a flexible term that helps most axes but extrapolates on one) is damped: its
model is blended with the step before, coefficients (1 - a) * before + a * refit, with the
largest a in 1, 0.9, ..., 0 that leaves no axis worse. The blend is itself a linear model of
the same terms (the parameters reported are the blended ones), and a = 0 is the step before,
so no step can be worse than its predecessor on any axis.

"Worse" allows for the resolution of a held-out p99: ``TOLERANCE_REL`` of the value plus
``TOLERANCE_PCT`` (% FS). Both are far below what the step is judged on (an axis that a step
takes from 5 % to 16 % FS, as a flexible term extrapolating can, is damped), and keep an axis
at the noise floor from damping a step that halves the error of the others. Without them (no
axis may rise at all) the one blend weight all axes share gives up whole steps over a hair on
one axis: any correction moves an axis at its noise floor by a hair either way, at first
order in the weight (on a development run, 0.003 % FS on an axis at 0.18 % FS damped every
step of a ladder entirely). The comparison is made on the very p99s the ladder reports (the
baseline's rounded as every step's).
"""
from __future__ import annotations

import numpy as np

ALPHAS = np.linspace(1.0, 0.0, 11)
TOLERANCE_REL = 0.02
TOLERANCE_PCT = 0.005


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


def monotone(y: np.ndarray, preds) -> tuple[list[float], list[np.ndarray], np.ndarray]:
    """``y`` (n, 6) FS-normalised residual, ``preds`` the held-out predictions of the refit
    after each step (any iterable: a generator lets each be freed once used). Returns the blend
    weight of each step, the held-out p99 (% FS) after each step, and the final blended
    prediction (only one (n, 6) array is kept: long logs). The steps start from
    :func:`baseline_p99`."""
    weights, p99s = [], []
    before = np.zeros_like(y)
    before_p99 = baseline_p99(y)
    for pred in preds:
        step = np.subtract(pred, before, dtype=float)        # pred - before
        for a in ALPHAS:
            if a == 0.0:                    # the step before, exactly (its reported p99s)
                trial, trial_p99 = before, before_p99
                break
            trial = before + a * step
            trial_p99 = p99_of_difference(y, trial)
            if np.all(trial_p99 <= before_p99 * (1 + TOLERANCE_REL) + TOLERANCE_PCT):
                break
        weights.append(float(a))
        p99s.append(trial_p99)
        before, before_p99 = trial, trial_p99
        del step
    return weights, p99s, before


def blend_coefficients(prev: np.ndarray, new: np.ndarray, a: float) -> np.ndarray:
    """Coefficients of the blend; ``prev`` covers the first len(prev) of ``new``'s columns
    (the terms added before), the rest start from zero. Works per fold too (last axis)."""
    padded = np.zeros_like(new)
    padded[..., :prev.shape[-1]] = prev
    return (1.0 - a) * padded + a * new
