"""The verdict's statistics on a regression whose answer is known: standard errors, the joints
a per-joint family stands out on, and the plausibility limit itself."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from delta6.diagnosis import selection, verdicts


def problem_of(x: np.ndarray, y: np.ndarray, widths: dict, blocks: int = 4,
               plausibility=None) -> selection.Problem:
    """A Problem over samples ``x`` (n, 6, P), ``y`` (n, 6), its Gram summaries per block."""
    n = len(y)
    bounds = np.linspace(0, n, blocks + 1).astype(int)
    gram = np.stack([np.einsum("nap,naq->pq", x[a:b], x[a:b]) for a, b in zip(bounds, bounds[1:])])
    xty = np.stack([np.einsum("nap,na->p", x[a:b], y[a:b]) for a, b in zip(bounds, bounds[1:])])
    yty = np.array([np.sum(y[a:b] ** 2) for a, b in zip(bounds, bounds[1:])])
    slices, at, terms = {}, 0, {}
    for name, width in widths.items():
        slices[name] = slice(at, at + width)
        at += width
        terms[name] = SimpleNamespace(param_names=[f"p{k}" for k in range(width)],
                                      plausibility=plausibility,
                                      sign_checks=lambda coef, cov: [], group=None,
                                      refines=None)
    return selection.Problem(y=y, x=x, slices=slices, terms=terms, bounds=bounds, gram=gram,
                             xty=xty, yty=yty)


def regression(seed: int, true: np.ndarray, n: int = 3000, noise: float = 1.0):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 6, len(true)))
    y = x @ true + noise * rng.normal(size=(n, 6))
    return x, y


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_standard_errors_are_ordinary_least_squares_without_a_prior(seed):
    true = np.array([0.3, 0.0, -0.2, 0.1, 0.0, 0.05, 0.4])
    x, y = regression(seed, true)
    problem = problem_of(x, y, {"per_joint": 6, "whole": 1})
    names = ["per_joint", "whole"]
    coef = selection.fit(problem, names)
    rows, cols = x.reshape(-1, 7), y.reshape(-1)
    ols, *_ = np.linalg.lstsq(rows, cols, rcond=None)
    np.testing.assert_allclose(coef, ols, atol=1e-10)
    sigma2 = np.sum((cols - rows @ ols) ** 2) / (len(cols) - 7)
    expected = np.sqrt(np.diag(np.linalg.inv(rows.T @ rows)) * sigma2)
    np.testing.assert_allclose(verdicts.standard_errors(problem, names, coef), expected,
                               rtol=1e-9)


def test_a_joint_counts_only_beyond_three_standard_errors():
    x, y = regression(7, np.zeros(7))
    problem = problem_of(x, y, {"per_joint": 6, "whole": 1})
    names = ["per_joint", "whole"]
    # Coefficients placed at a chosen number of their own standard errors (the errors
    # depend a little on the coefficients through the residual variance: iterate).
    sigmas = np.array([0.0, 2.9, 3.1, -3.1, -2.9, 10.0, 5.0])
    coef = np.zeros(7)
    for _ in range(20):
        coef = sigmas * verdicts.standard_errors(problem, names, coef)
    assert verdicts.significant_joints(problem, names, coef, "per_joint") == {3, 4, 6}
    # A family that is not per joint stands for every joint; one not in the model for none.
    assert verdicts.significant_joints(problem, names, coef, "whole") == set(range(1, 7))
    assert verdicts.significant_joints(problem, names, coef, "absent") == set()


def test_a_per_joint_family_found_on_the_joints_it_acts_on():
    true = np.array([0.3, 0.0, 0.2, 0.0, 0.0, -0.15, 0.0])   # whole, then joints 1..6
    x, y = regression(11, true)
    problem = problem_of(x, y, {"whole": 1, "per_joint": 6})
    names = ["whole", "per_joint"]
    coef = selection.fit(problem, names)
    # The per-joint family's columns come second here: its coefficients are found by name.
    assert verdicts.significant_joints(problem, names, coef, "per_joint") == {2, 5}


@pytest.mark.parametrize("ratio, plausible", [(0.5, True), (1.0, True), (1.0001, False)])
def test_a_family_is_plausible_up_to_its_limit_inclusive(ratio, plausible):
    x, y = regression(3, np.array([0.1, 0.2]))
    seen = []

    def checks(coef, cov):
        seen.append((coef.copy(), cov.copy()))
        return [{"quantity": "q", "ratio": 0.2}, {"quantity": "r", "ratio": ratio}]

    problem = problem_of(x, y, {"a": 1, "b": 1}, plausibility=checks)
    coef = selection.fit(problem, ["a", "b"])
    out = verdicts.plausibility(problem, ["a", "b"], coef)
    assert out["a"]["plausible"] is plausible and out["b"]["plausible"] is plausible
    # Each family is judged on its own coefficients and their block of the covariance.
    cov = verdicts.covariance(problem, ["a", "b"], coef)
    se = verdicts.standard_errors(problem, ["a", "b"], coef)
    for k, (c, block) in enumerate(seen):
        np.testing.assert_array_equal(c, coef[k:k + 1])
        np.testing.assert_array_equal(block, cov[k:k + 1, k:k + 1])
        np.testing.assert_allclose(np.sqrt(np.diag(block)), se[k:k + 1])


@pytest.mark.parametrize("seed", [1, 2])
def test_a_family_another_fits_as_well_has_that_one_as_a_stand_in(seed):
    # "b" is "a"'s column with a little noise of its own: the log cannot tell them apart;
    # "c" is unrelated and fits nothing.
    rng = np.random.default_rng(seed)
    n = 3000
    a = rng.normal(size=(n, 6, 1))
    x = np.concatenate([a, a + 0.01 * rng.normal(size=(n, 6, 1)),
                        rng.normal(size=(n, 6, 1))], axis=2)
    y = a[..., 0] + rng.normal(size=(n, 6))
    problem = problem_of(x, y, {"a": 1, "b": 1, "c": 1}, blocks=12,
                         plausibility=lambda coef, cov: [])
    problem.folds = selection.make_folds(12, n_folds=3, run=1)
    problem.noise_var = 1.0
    assert verdicts.stand_ins(problem, ["a"], ["a"], ["b", "c"]) == {"a": ["b"]}
    # Without a noise floor to judge against, no swap is within it.
    problem.noise_var = 0.0
    assert verdicts.stand_ins(problem, ["a"], ["a"], ["b", "c"]) == {}
    # One of a declared group is left to the group verdicts, one refining it to those rules.
    problem.noise_var = 1.0
    problem.terms["a"].group = problem.terms["b"].group = "same"
    assert verdicts.stand_ins(problem, ["a"], ["a"], ["b", "c"]) == {}
    problem.terms["b"].group = None
    problem.terms["b"].refines = "a"
    assert verdicts.stand_ins(problem, ["a"], ["a"], ["b", "c"]) == {}
    problem.terms["b"].refines = None
    assert verdicts.stand_ins(problem, ["a"], [], ["b", "c"]) == {}
    # A stand-in that fits only out of bounds is none.
    problem.terms["b"].plausibility = lambda coef, cov: [{"quantity": "q", "ratio": 2.0}]
    assert verdicts.stand_ins(problem, ["a"], ["a"], ["b", "c"]) == {}


def test_a_loose_look_alike_is_no_stand_in():
    # "b" shares 60 % of "a"'s column: near the noise floor its swap stays within the noise
    # criterion, but it wins back well under half of what taking "a" out costs.
    rng = np.random.default_rng(5)
    n = 3000
    a = rng.normal(size=(n, 6, 1))
    b = 0.6 * a + 0.8 * rng.normal(size=(n, 6, 1))
    x = np.concatenate([a, b], axis=2)
    y = 0.57 * a[..., 0] + rng.normal(size=(n, 6))
    problem = problem_of(x, y, {"a": 1, "b": 1}, blocks=12,
                         plausibility=lambda coef, cov: [])
    problem.folds = selection.make_folds(12, n_folds=3, run=1)
    problem.noise_var = 1.0
    full = selection.heldout_block_sse(problem, ["a"]).sum()
    cost = selection.heldout_block_sse(problem, []).sum() - full
    swap = selection.heldout_block_sse(problem, ["b"]).sum() - full
    floor = verdicts.noise_floor_sse(problem)
    assert verdicts.above_noise(cost, floor) and not verdicts.above_noise(swap, floor)
    assert cost - swap < verdicts.STAND_IN_SHARE * cost
    assert verdicts.stand_ins(problem, ["a"], ["a"], ["b"]) == {}
