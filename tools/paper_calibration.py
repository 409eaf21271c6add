#!/usr/bin/env python3
"""How the twin's `paper` scenario was calibrated (docs/twin.md, "The paper scenario").

Every effect of the scenario but one is set by physical reasoning (fixed values in
``delta6.twin.scenarios.PAPER``). The unknowns are the spring-rate deviations of joints 1..5
(the paper calibrated k on joint 6 only, so joint 6 keeps a small fixed deviation): five
unknowns fitted, in the least-squares sense, to the six p99 entries of the paper's Table V
analytical row on one 2000 s run (seed CAL_SEED), then checked on other seeds.

    .venv/bin/python tools/paper_calibration.py            # fit and verify (~1 min)
    .venv/bin/python tools/paper_calibration.py --verify   # only the table for the scenario as shipped
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))

from delta6.design import load  # noqa: E402
from delta6.model import AXES  # noqa: E402
from delta6.twin import build_effects, scenario_effects, simulate  # noqa: E402
from delta6.twin.scenarios import PAPER  # noqa: E402

#: The paper's Table V, analytical rows (% FS).
TABLE_V = {"p95": [3.81, 4.62, 2.58, 5.45, 5.41, 3.42],
           "p99": [5.06, 6.50, 3.64, 7.08, 6.92, 4.34],
           "p100": [7.16, 9.76, 6.39, 11.12, 9.44, 5.67]}
CAL_SEED = 2026
VERIFY_SEEDS = (1, 2, 3)
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


def p99(design, u: np.ndarray, seed: int = CAL_SEED) -> np.ndarray:
    result = simulate(design, build_effects(requests_for(u), seed), DURATION_S, seed=seed)
    return np.array(result.gap((99,))["p99"])


def fit(design, u0: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Independent error sources add in quadrature, so p99^2 is close to linear in the squared
    unknowns: Gauss-Newton steps in that space (finite-difference sensitivities), kept
    non-negative, least squares where the six targets cannot all be met."""
    target = np.array(TABLE_V["p99"])
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
    print(f"{'':14}" + "".join(f"{a:>7}" for a in AXES))
    for key in ("p95", "p99", "p100"):
        print(f"{'paper ' + key:14}" + "".join(f"{v:7.2f}" for v in TABLE_V[key]))
        for seed in seeds:
            r = simulate(design, effects_for_seed(seed), DURATION_S, seed=seed)
            row = r.gap((int(key[1:]),))[key]
            print(f"{'  seed ' + str(seed):14}" + "".join(f"{v:7.2f}" for v in row))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--verify", action="store_true", help="only verify the shipped scenario")
    args = parser.parse_args()
    design = load(ROOT / "designs" / "delta6.toml")
    started = time.perf_counter()
    if not args.verify:
        u0 = np.array([0.04, 0.05, 0.04, 0.06, 0.06])
        print(f"fitting the joint 1..5 spring-rate deviations (seed {CAL_SEED}, "
              f"{DURATION_S:g} s)")
        u = fit(design, u0)
        print("\nresult, to paste into delta6/twin/scenarios.py (PAPER):")
        print("  deviation = [" + ", ".join(f"{v:.4f}" for v in deviations(u)) + "]")
    print(f"\nthe shipped `paper` scenario against Table V (% FS), {DURATION_S:g} s runs:")
    table(design, lambda seed: scenario_effects("paper", seed), (CAL_SEED,) + VERIFY_SEEDS)
    print(f"\n({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
