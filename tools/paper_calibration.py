#!/usr/bin/env python3
"""How the twin's `paper` scenario was calibrated (docs/twin.md, "The paper scenario").

Every effect of the scenario but one is set by physical reasoning (fixed values in
``delta6.twin.scenarios.PAPER``). The unknowns are the spring-rate deviations of joints 1..5
(the paper calibrated k on joint 6 only, so joint 6 keeps a small fixed deviation): five
unknowns fitted, in the least-squares sense, to the six p99 entries of the paper's Table V
analytical row (pulled inside the required band where they are close to its edge: FIT_TARGET)
on six pooled 2000 s runs (seeds CAL_SEEDS), then checked on other seeds.

    .venv/bin/python tools/paper_calibration.py            # fit and verify (~6 min)
    .venv/bin/python tools/paper_calibration.py --verify   # only the table for the scenario as shipped
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from delta6.core.accuracy import error_pct_fs
from delta6.core.design import load
from delta6.core.model import AXES
from delta6.core.spec import full_scale
from delta6.twin import build_effects, scenario_effects, simulate
from delta6.twin.scenarios import PAPER

ROOT = Path(__file__).resolve().parents[1]


#: The paper's Table V, analytical rows (% FS).
TABLE_V = {"p95": [3.81, 4.62, 2.58, 5.45, 5.41, 3.42],
           "p99": [5.06, 6.50, 3.64, 7.08, 6.92, 4.34],
           "p100": [7.16, 9.76, 6.39, 11.12, 9.44, 5.67]}
#: What the fit aims at: Table V's p99 row, pulled inside the required band [3.5, 7.5] % FS by
#: 2.5 times the seed-to-seed scatter of each axis's p99 (SCATTER, the standard deviation over
#: 2000 s runs of different seeds, printed by --verify), so that a run of any seed lands in the
#: band. Only Fz (printed close to the band's lower edge) moves, to 4.12.
BAND = (3.5, 7.5)
SCATTER = np.array([0.24, 0.29, 0.25, 0.13, 0.07, 0.12])
FIT_TARGET = np.clip(TABLE_V["p99"], BAND[0] + 2.5 * SCATTER, BAND[1] - 2.5 * SCATTER)
CAL_SEEDS = (2026, 2027, 2028, 2029, 2030, 2031)
VERIFY_SEEDS = tuple(range(1, 13))
DURATION_S = 2000.0
JOINT6_DEVIATION = 0.005
#: Signs of the joint 1..5 deviations (a choice: mixed, as springs off a shelf are). The joints'
#: deflections vary independently, so the signs barely change the percentiles.
SIGNS = np.array([1.0, -1.0, 1.0, 1.0, -1.0])


def deviations(u: np.ndarray) -> list[float]:
    """Six spring-rate deviations from the unknowns u = |deviation| of joints 1..5."""
    return [*(SIGNS * u[:5]), JOINT6_DEVIATION]


def requests_for(u: np.ndarray):
    """The PAPER requests with the six unknowns substituted."""
    out = []
    for r in PAPER:
        if r.name == "stiffness_mismatch":
            r = replace(r, params={"deviation": deviations(u)})
        out.append(r)
    return out


def p99(design, u: np.ndarray) -> np.ndarray:
    """p99 % FS per axis over the pooled calibration runs."""
    errors = []
    for seed in CAL_SEEDS:
        result = simulate(design, build_effects(requests_for(u), seed), DURATION_S, seed=seed)
        errors.append(error_pct_fs(result.model_wrench(), result.wrench, full_scale(design)))
    return np.percentile(np.concatenate(errors), 99, axis=0)


def fit(design, u0: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Independent error sources add in quadrature, so p99^2 is close to linear in the squared
    unknowns: Gauss-Newton steps in that space (finite-difference sensitivities), kept
    non-negative, least squares where the six targets cannot all be met."""
    target = FIT_TARGET
    u = u0.copy()
    best, best_error = u, np.inf
    for it in range(iterations + 1):
        y = p99(design, u)
        error = np.sqrt(np.mean((y - target) ** 2))
        print(f"  iteration {it}: p99 " + " ".join(f"{v:5.2f}" for v in y)
              + f"   rms error {error:.3f}", flush=True)
        if error < best_error:
            best, best_error = u, error
        if it == iterations:
            break
        v = u**2
        sens = np.empty((6, len(u)))
        for j in range(len(u)):
            bumped = u.copy()
            bumped[j] *= 1.3
            sens[:, j] = (p99(design, bumped) ** 2 - y**2) / (bumped[j] ** 2 - v[j])
        v = _nonnegative_solve(sens, target**2 - y**2 + sens @ v)
        u = np.sqrt(np.maximum(v, (0.2 * u) ** 2))
    return best


def _nonnegative_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min |a x - b| subject to x >= 0, by dropping the most negative unknown until none is."""
    free = np.ones(a.shape[1], dtype=bool)
    x = np.zeros(a.shape[1])
    while free.any():
        sol, *_ = np.linalg.lstsq(a[:, free], b, rcond=None)
        if (sol >= 0).all():
            x[free] = sol
            break
        free[np.flatnonzero(free)[np.argmin(sol)]] = False
    return x


def table(design, effects_for_seed, seeds) -> None:
    """Table V rows next to the twin's, per seed, and the p99 mean and scatter over seeds."""
    rows = {key: [] for key in TABLE_V}
    for seed in seeds:
        result = simulate(design, effects_for_seed(seed), DURATION_S, seed=seed)
        gap = result.truth["analytical_error_pct_fs"]   # p50, p95, p99 and p100
        for key in TABLE_V:
            rows[key].append(gap[key])
    print(f"{'':14}" + "".join(f"{a:>7}" for a in AXES))
    for key in TABLE_V:
        print(f"{'paper ' + key:14}" + "".join(f"{v:7.2f}" for v in TABLE_V[key]))
        for seed, row in zip(seeds, rows[key]):
            print(f"{'  seed ' + str(seed):14}" + "".join(f"{v:7.2f}" for v in row))
    p99 = np.array(rows["p99"])
    print(f"{'p99 mean':14}" + "".join(f"{v:7.2f}" for v in p99.mean(axis=0)))
    print(f"{'p99 scatter':14}" + "".join(f"{v:7.2f}" for v in p99.std(axis=0, ddof=1)))
    print(f"{'p99 min':14}" + "".join(f"{v:7.2f}" for v in p99.min(axis=0)))
    print(f"{'p99 max':14}" + "".join(f"{v:7.2f}" for v in p99.max(axis=0)))
    inside = np.all((p99 >= BAND[0]) & (p99 <= BAND[1]), axis=1)
    print(f"runs with every axis in [{BAND[0]:g}, {BAND[1]:g}] % FS: {inside.sum()} of {len(seeds)}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--verify", action="store_true", help="only verify the shipped scenario")
    args = parser.parse_args()
    design = load(ROOT / "designs" / "delta6.toml")
    started = time.perf_counter()
    if not args.verify:
        u0 = np.array([0.04, 0.05, 0.04, 0.06, 0.06])
        print(f"fitting the joint 1..5 spring-rate deviations (seeds {CAL_SEEDS}, "
              f"{DURATION_S:g} s each) to p99 " + " ".join(f"{v:.2f}" for v in FIT_TARGET))
        u = fit(design, u0)
        print("\nresult, to paste into delta6/twin/scenarios.py (PAPER):")
        print("  deviation = [" + ", ".join(f"{v:.4f}" for v in deviations(u)) + "]")
    print(f"\nthe shipped `paper` scenario against Table V (% FS), {DURATION_S:g} s runs:")
    table(design, lambda seed: scenario_effects("paper", seed), VERIFY_SEEDS)
    print(f"\n({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
