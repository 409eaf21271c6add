"""Sequential state without a Python loop per sample: blocked scans of associative maps.

The history operators of the digital twin's effects and of the gap diagnosis's candidate terms
(play operators, first-order lags) share this one implementation. Each advances its state with
a per-sample map from a family that is closed under composition:

* affine maps ``x -> a x + b`` (first-order lags, the Dahl/Bouc-Wen hysteresis and the LuGre
  bristle, both integrated exactly over a sample),
* clamps ``x -> min(max(x, lo), hi)`` (the play operator of backlash and of the
  Prandtl-Ishlinskii hysteresis).

The state after n samples is the composition of the first n maps applied to the initial state.
Composition is associative, so the samples are cut into about sqrt(N) blocks: one pass composes
the maps inside all blocks at once (vectorised across blocks), a short pass carries the state
from block to block, and a last vectorised step applies the in-block prefixes. That is about
2 sqrt(N) numpy operations on small arrays instead of N Python iterations.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

Maps = tuple[np.ndarray, ...]


#: Columns scanned together: wider arrays fall out of the cache and get slower per element.
_COLUMNS_PER_PASS = 8


def _blocked_scan(maps: Maps, identity: tuple[float, ...], x0: np.ndarray,
                  compose: Callable[[Maps, Maps], Maps],
                  apply: Callable[[Maps, np.ndarray], np.ndarray]) -> np.ndarray:
    """States x_1..x_N of x_n = f_n(x_{n-1}); ``maps`` hold the parameters of f_n along axis 0."""
    n = len(maps[0])
    tail = maps[0].shape[1:]
    x0 = np.broadcast_to(np.asarray(x0, dtype=float), tail).reshape(-1)
    if n == 0:
        return np.empty((0,) + tail)
    flat = [np.asarray(m, dtype=float).reshape(n, -1) for m in maps]
    out = np.empty((n, x0.size))
    for c in range(0, x0.size, _COLUMNS_PER_PASS):
        cols = slice(c, c + _COLUMNS_PER_PASS)
        out[:, cols] = _scan_columns(tuple(m[:, cols] for m in flat), identity, x0[cols],
                                     compose, apply)
    return out.reshape((n,) + tail)


def _scan_columns(maps: Maps, identity, x0, compose, apply) -> np.ndarray:
    n = len(maps[0])
    tail = maps[0].shape[1:]
    size = max(1, math.isqrt(n))
    blocks = -(-n // size)
    # Layout (position in block, block, ...): one position of every block is contiguous.
    padded = []
    for m, ident in zip(maps, identity):
        full = np.full((blocks * size,) + tail, ident, dtype=float)
        full[:n] = m
        padded.append(np.ascontiguousarray(np.swapaxes(full.reshape((blocks, size) + tail), 0, 1)))
    # In-block inclusive prefixes, all blocks at once.
    for s in range(1, size):
        prev = tuple(p[s - 1] for p in padded)
        cur = tuple(p[s] for p in padded)
        for p, value in zip(padded, compose(cur, prev)):
            p[s] = value
    # The state entering each block.
    starts = np.empty((blocks,) + tail)
    x = x0
    for b in range(blocks):
        starts[b] = x
        x = apply(tuple(p[size - 1, b] for p in padded), x)
    out = apply(tuple(padded), starts[None])
    return np.swapaxes(out, 0, 1).reshape((blocks * size,) + tail)[:n]


def affine_scan(a: np.ndarray, b: np.ndarray, x0) -> np.ndarray:
    """x_n = a_n x_{n-1} + b_n for n = 1..N (a, b of shape (N, ...)); returns x_1..x_N."""
    a = np.asarray(a, dtype=float)
    b = np.broadcast_to(np.asarray(b, dtype=float), a.shape)
    return _blocked_scan(
        (a, b), (1.0, 0.0), x0,
        compose=lambda g, f: (g[0] * f[0], g[0] * f[1] + g[1]),
        apply=lambda f, x: f[0] * x + f[1])


def clamp_scan(lo: np.ndarray, hi: np.ndarray, x0) -> np.ndarray:
    """x_n = min(max(x_{n-1}, lo_n), hi_n) (lo_n <= hi_n); returns x_1..x_N."""
    lo = np.asarray(lo, dtype=float)
    hi = np.broadcast_to(np.asarray(hi, dtype=float), lo.shape)

    def apply(f, x):
        return np.minimum(np.maximum(x, f[0]), f[1])

    return _blocked_scan((lo, hi), (-np.inf, np.inf), x0,
                         compose=lambda g, f: (apply(g, f[0]), apply(g, f[1])), apply=apply)


def play(x: np.ndarray, radius, y0=None) -> np.ndarray:
    """The play (backlash) operator along axis 0: the output stays put until the input is more
    than ``radius`` away, then is dragged along at that distance. ``y0`` defaults to x[0].

    ``radius`` broadcasts against ``x``: ``play(x[:, None, :], radii)`` with radii (r, m) runs
    r operators on every column of x (n, m) without copying x r times. A sum of play operators
    of different radii is the Prandtl-Ishlinskii model of rate-independent hysteresis: the
    output depends on the turning points of the history, never on how fast the input moved
    between them.
    """
    x = np.asarray(x, dtype=float)
    radius = np.asarray(radius, dtype=float)
    y0 = x[0] if y0 is None else y0
    return clamp_scan(x - radius, x + radius, y0)


def first_order(x: np.ndarray, a: float, x0=None) -> np.ndarray:
    """First-order lag along axis 0 with a constant pole: y_n = a y_(n-1) + (1 - a) x_n,
    from y_0 = ``x0`` (default x[0]: started settled). On a uniform grid of step dt,
    a = exp(-dt / tau) is the exact lag of time constant tau for an input held over each step,
    a = tau / (tau + dt) its backward-Euler form."""
    x = np.asarray(x, dtype=float)
    return affine_scan(np.full(x.shape, a), (1.0 - a) * x, x[0] if x0 is None else x0)
