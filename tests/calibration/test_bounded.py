"""The constrained least squares of the calibration's fit: its answer satisfies the optimality
conditions of the convex problem, and without binding constraints it is the diagnosis's
unconstrained solve."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from delta6.calibration import bounded
from delta6.diagnosis.selection import solve as unconstrained


def _problem(seed, n, m, scale_spread):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(3 * n, n)) * np.exp(rng.uniform(-scale_spread, scale_spread, n))
    h = x.T @ x + np.diag(rng.uniform(0.0, 1.0, n))
    v = rng.normal(size=n) * np.sqrt(np.diag(h)) * 3
    a = rng.normal(size=(m, n)) * (rng.uniform(size=(m, n)) < 0.5)
    a[np.abs(a).sum(axis=1) == 0, 0] = 1.0
    b = -rng.uniform(0.0, 1.0, m) * (rng.uniform(size=m) < 0.5)    # zero is feasible
    return h, v, a, b


def _brute_force(h, v, a, b):
    """The minimum over every subset of constraints held with equality (feasible answers
    only): the convex problem's minimum is one of them."""
    n, best, best_x = len(v), np.inf, None
    for mask in itertools.product([False, True], repeat=len(b)):
        aw, bw = a[list(mask)], b[list(mask)]
        k = len(bw)
        kkt = np.block([[h, -aw.T], [aw, np.zeros((k, k))]])
        try:
            x = np.linalg.solve(kkt, np.concatenate([v, bw]))[:n]
        except np.linalg.LinAlgError:
            continue
        if np.all(a @ x >= b - 1e-9 * (1 + np.abs(b))):
            f = 0.5 * x @ h @ x - v @ x
            if f < best:
                best, best_x = f, x
    return best, best_x


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 8), m=st.integers(0, 6),
       spread=st.floats(0.0, 6.0))
# Ill-conditioned, three constraints active at the start: the rounding of the zero step on
# their plane stayed above the tolerance and the iterations never ended.
@example(seed=4_294_967_295, n=4, m=4, spread=6.0)
@example(seed=82_647_848, n=4, m=6, spread=5.98)
def test_the_answer_is_the_constrained_minimum(seed, n, m, spread):
    h, v, a, b = _problem(seed, n, m, spread)
    x = bounded.solve(h, v, a, b)
    scale = np.sqrt(np.diag(h))
    assert np.all(a @ x >= b - 1e-8 * (1 + np.abs(b))), "infeasible"
    best, best_x = _brute_force(h, v, a, b)
    f = 0.5 * x @ h @ x - v @ x
    # The same minimum (the solver's tiny ridge aside), and the same point: the problem is
    # strictly convex.
    assert f <= best + 1e-7 * max(1.0, abs(best))
    np.testing.assert_allclose(x * scale, best_x * scale, atol=1e-5 * max(1.0, np.abs(
        best_x * scale).max()))


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12))
def test_without_binding_constraints_it_is_the_unconstrained_solve(seed, n):
    h, v, _, _ = _problem(seed, n, 0, 2.0)
    free = unconstrained(h, v)
    # Bounds below the free answer (and below zero, the start) never bind.
    below = np.minimum(free - 1.0, 0.0)
    np.testing.assert_allclose(bounded.solve(h, v, np.eye(n), below), free, rtol=1e-8,
                               atol=1e-12)
    np.testing.assert_allclose(bounded.solve(h, v), free, rtol=1e-9, atol=1e-12)


def test_a_bound_binds_where_the_free_answer_breaks_it():
    h = np.array([[2.0, 0.5], [0.5, 1.0]])
    v = np.array([-1.0, 1.0])
    x = bounded.solve(h, v, np.eye(2), np.zeros(2))
    # x0 is held at 0; x1 is then the one-dimensional minimum, v1 / h11.
    np.testing.assert_allclose(x, [0.0, 1.0], atol=1e-12)


def test_an_infeasible_start_is_refused():
    with pytest.raises(ValueError):
        bounded.solve(np.eye(2), np.ones(2), np.eye(2), np.ones(2))
