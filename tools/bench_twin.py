#!/usr/bin/env python3
"""Generation time of the digital twin: 10^5 samples (2000 s at 50 Hz) per scenario.

    .venv/bin/python tools/bench_twin.py              # every scenario and formulation
    .venv/bin/python tools/bench_twin.py --quick      # ideal, paper, everything at once

Prints, per scenario, the simulation time, the time to write the log and truth file, the
analytical model's worst-axis p99 (% FS), and the process's peak memory at the end.
"""
from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

from delta6.core.design import load
from delta6.twin import EFFECT_NAMES, REGISTRY, make_effect, scenario_effects, simulate, write_log

ROOT = Path(__file__).resolve().parents[1]


DURATION_S, RATE_HZ, SEED = 2000.0, 50.0, 1


def cases(quick: bool):
    yield "ideal", []
    yield "paper", scenario_effects("paper", SEED)
    yield "all nine effects", [make_effect(n, SEED) for n in EFFECT_NAMES]
    if quick:
        return
    for name in EFFECT_NAMES:
        for formulation in REGISTRY[name].FORMULATIONS:
            yield f"{name}:{formulation}", [make_effect(name, SEED, formulation=formulation)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    design = load(ROOT / "designs" / "delta6.toml")
    simulate(design, [], 10.0, RATE_HZ, SEED)   # warm up imports and caches
    print(f"{int(DURATION_S * RATE_HZ)} samples ({DURATION_S:g} s at {RATE_HZ:g} Hz), seed {SEED}")
    print(f"{'scenario':34} {'simulate s':>10} {'write s':>8} {'worst p99 %FS':>14}")
    with tempfile.TemporaryDirectory() as tmp:
        for label, effects in cases(args.quick):
            started = time.perf_counter()
            result = simulate(design, effects, DURATION_S, RATE_HZ, SEED)
            simulated = time.perf_counter() - started
            started = time.perf_counter()
            write_log(result, Path(tmp) / "bench.csv")
            written = time.perf_counter() - started
            worst = max(result.truth["analytical_error_pct_fs"]["p99"])
            print(f"{label:34} {simulated:10.2f} {written:8.2f} {worst:14.2f}", flush=True)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak memory {peak_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
