"""Least squares from normal equations under linear inequality constraints (a small convex QP).

The calibration's fit solves ``(G + P) x = v`` for each Gauss-Newton step; some parameters
have a sign that physics fixes (a passive friction torque opposes the motion, the reference
sensor can only be late). :func:`solve` minimises ``x^T H x / 2 - v^T x`` subject to
``A x >= b`` by a primal active-set method (Nocedal and Wright, Numerical Optimization,
algorithm 16.3): from a feasible start, each iteration solves the equality-constrained problem
on the active constraints, steps as far as the others allow, and drops an active constraint
whose multiplier is negative. The problems are small (a hundred parameters, tens of
constraints), so each iteration is one dense solve. Without active constraints the answer is
the unconstrained solution, scaled and ridged exactly like ``delta6.diagnosis.selection.solve``.
"""
from __future__ import annotations

import numpy as np

from delta6.diagnosis.selection import RIDGE

#: Relative tolerance of feasibility and of a zero step (in the diagonal-scaled variables).
TOL = 1e-10


def _scaled(h: np.ndarray):
    scale = np.sqrt(np.maximum(np.diag(h), 1e-300))
    g = h / np.outer(scale, scale)
    g[np.diag_indices_from(g)] += RIDGE * max(1.0, np.trace(g) / len(g))
    return g, scale


def solve(h: np.ndarray, v: np.ndarray, a: np.ndarray | None = None, b: np.ndarray | None = None,
          start: np.ndarray | None = None, max_iterations: int | None = None) -> np.ndarray:
    """argmin x^T h x / 2 - v^T x subject to a x >= b (h symmetric positive definite). ``start``
    must be feasible (default: zero, which must then be). Raises ValueError on an infeasible
    start."""
    v = np.asarray(v, dtype=float)
    n = len(v)
    if n == 0:
        return np.zeros(0)
    hs, scale = _scaled(np.asarray(h, dtype=float))
    vs = v / scale
    if a is None or len(a) == 0:
        return np.linalg.solve(hs, vs) / scale
    a = np.asarray(a, dtype=float) / scale[None, :]
    b = np.asarray(b, dtype=float)
    norm = np.maximum(np.linalg.norm(a, axis=1), 1e-300)
    a, b = a / norm[:, None], b / norm                 # unit rows: one tolerance for all
    y = np.zeros(n) if start is None else np.asarray(start, dtype=float) * scale
    tol = TOL * max(1.0, float(np.max(np.abs(y))))
    if np.any(a @ y < b - tol):
        raise ValueError("the start violates the constraints")
    # Only the constraints that hold with equality at the start begin active.
    active = [i for i in np.flatnonzero(np.abs(a @ y - b) <= tol)]
    active = _independent(a, active)
    m = len(b)
    # After a full, unblocked step y is the minimum on the active constraints' plane: the next
    # step is zero in exact arithmetic, but in an ill-conditioned problem its rounding can stay
    # above any fixed tolerance, and chasing it never ends.
    on_plane_minimum = False
    for _ in range(max_iterations or 10 * (n + m)):
        p, lam = _equality_step(hs, vs, a, active, y)
        if on_plane_minimum or np.max(np.abs(p)) <= TOL * max(1.0, float(np.max(np.abs(y)))):
            if not active or lam.min() >= -TOL:
                return y / scale
            active.pop(int(np.argmin(lam)))
            on_plane_minimum = False
            continue
        ap = a @ p
        slack = a @ y - b
        alpha, blocking = 1.0, None
        # A constraint parallel to an active one sees the step as zero, up to rounding.
        toward = -TOL * float(np.max(np.abs(p)))
        for i in range(m):
            if i not in active and ap[i] < toward:
                reach = max(slack[i], 0.0) / -ap[i]
                # A constraint that depends on the active ones cannot block a step along
                # their plane; it only seems to, by rounding (and would stall the iterations).
                if reach < alpha and len(_independent(a, active + [i])) > len(active):
                    alpha, blocking = reach, i
        y = y + alpha * p
        on_plane_minimum = blocking is None
        if blocking is not None:
            active.append(blocking)
    raise RuntimeError("the active-set iterations did not converge")


def _independent(a: np.ndarray, rows: list) -> list:
    """The rows of ``rows`` that are linearly independent of the ones before them."""
    kept: list = []
    for i in rows:
        if np.linalg.matrix_rank(a[kept + [i]]) == len(kept) + 1:
            kept.append(i)
    return kept


def _equality_step(h, v, a, active, y):
    """The step p from y to the minimum on the active constraints' plane (a_W p = 0), and
    their multipliers."""
    n, k = len(v), len(active)
    kkt = np.zeros((n + k, n + k))
    kkt[:n, :n] = h
    aw = a[active]
    kkt[:n, n:] = -aw.T
    kkt[n:, :n] = aw
    rhs = np.concatenate([v - h @ y, np.zeros(k)])
    sol = np.linalg.solve(kkt, rhs)
    return sol[:n], sol[n:]
