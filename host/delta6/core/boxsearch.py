"""Global maximisation of smooth functions over a small box (the joint box of a design).

The design report needs the exact extremes of model quantities over the 3-D or 6-D joint box,
and the design check needs the worst case of the kinematics. The functions are smooth and have
few local optima, so a dense seed grid followed by a shrinking coordinate search from the best
seeds converges to the global optimum far below the 4 significant digits the report prints.
Everything is batched: ``f`` maps an (N, dim) array of points to N values.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

Objective = Callable[[np.ndarray], np.ndarray]


def grid(lo: np.ndarray, hi: np.ndarray, n: int) -> np.ndarray:
    """A tensor grid with ``n`` points per axis over the box, shape (n**dim, dim)."""
    axes = [np.linspace(a, b, n) for a, b in zip(lo, hi)]
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack(mesh, axis=-1).reshape(-1, len(axes))


def maximize(f: Objective, lo, hi, *, seeds: int = 9, starts: int = 8, line_points: int = 17,
             passes: int = 24, shrink: float = 0.35,
             extra_starts: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """Largest value of ``f`` over the box [lo, hi] and where it is attained.

    Seeds on an odd grid (it holds the centre and the faces), keeps the ``starts`` best seeds,
    then refines each by coordinate line searches whose span shrinks by ``shrink`` per pass.
    ``extra_starts`` adds caller-chosen seed points (e.g. the best of a cheaper separable
    evaluation). Non-finite values of ``f`` count as -inf.
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    dim = lo.size
    pts = grid(lo, hi, seeds)
    if extra_starts is not None:
        pts = np.concatenate([pts, np.asarray(extra_starts, dtype=float).reshape(-1, dim)])
    vals = _finite(f(pts))
    order = np.argsort(vals)[::-1][:starts]
    x = pts[order].copy()
    best = vals[order].copy()
    span = (hi - lo).copy()
    offsets = np.linspace(-1.0, 1.0, line_points)
    for _ in range(passes):
        for axis in range(dim):
            trial = np.repeat(x[:, None, :], line_points, axis=1)
            cand = np.clip(x[:, axis, None] + offsets[None, :] * span[axis], lo[axis], hi[axis])
            trial[:, :, axis] = cand
            tv = _finite(f(trial.reshape(-1, dim))).reshape(len(x), line_points)
            pick = np.argmax(tv, axis=1)
            improved = tv[np.arange(len(x)), pick] > best
            x[improved, axis] = cand[improved, pick[improved]]
            best = np.maximum(best, tv[np.arange(len(x)), pick])
        span *= shrink
    i = int(np.argmax(best))
    return float(best[i]), x[i]


def minimize(f: Objective, lo, hi, **kwargs) -> tuple[float, np.ndarray]:
    """Smallest value of ``f`` over the box, and where (see :func:`maximize`)."""
    value, where = maximize(lambda pts: -f(pts), lo, hi, **kwargs)
    return -value, where


def _finite(values: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    return np.where(np.isfinite(values), values, -np.inf)
