#!/usr/bin/env python3
"""Blind benchmark of the gap diagnosis on fresh digital-twin scenarios.

    .venv/bin/python tools/gap_benchmark.py                 # the full benchmark (~10 min)
    .venv/bin/python tools/gap_benchmark.py --quick         # one magnitude, fewer pairs
    .venv/bin/python tools/gap_benchmark.py --seed 123 --out results/

Prints progress, the figures (top-1 on single effects, false positives, pairs, parameter
recovery, predicted vs true shrink, run time), the confusion matrix and the paper scenario's
ladder; writes benchmark.json and benchmark.md into --out.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--design", default=str(ROOT / "designs" / "delta6.toml"))
    parser.add_argument("--seed", type=int, default=None, help="base seed (default: fresh)")
    parser.add_argument("--duration", type=float, default=600.0, help="seconds per run")
    parser.add_argument("--pairs", type=int, default=24)
    parser.add_argument("--none", type=int, default=10, dest="n_none")
    parser.add_argument("--quick", action="store_true",
                        help="one magnitude per effect, 8 pairs, 4 no-effect runs, no paper")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", default=str(ROOT / "build" / "gap-benchmark"))
    args = parser.parse_args()

    from delta6.core.design import load
    from delta6.diagnosis import benchmark as bench

    seed = bench.DEFAULT_BASE_SEED if args.seed is None else args.seed
    if args.quick:
        cases = bench.plan(seed, magnitudes=(0.8,), n_pairs=8, n_none=4, paper=False)
    else:
        cases = bench.plan(seed, n_pairs=args.pairs, n_none=args.n_none)
    design = load(args.design)
    print(f"gap benchmark: {len(cases)} blind cases, {args.duration:g} s each, "
          f"{args.jobs} jobs, base seed {seed}", flush=True)

    def progress(done, total, r):
        truth = ", ".join(f"{t['name']}/{t['formulation']}" for t in r["truth"]) or r["kind"]
        mark = "ok " if ({t["name"] for t in r["truth"]} <= set(r["present"])
                         and (r["truth"] or not r["present"])) else "MISS"
        print(f"  [{done:3d}/{total}] {mark} {truth:<55} -> {r['present'] or ['nothing']} "
              f"({r['seconds']:.1f} s)", flush=True)

    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="delta6-gap-") as work:
        results = bench.run(cases, args.design, args.duration, work, jobs=args.jobs,
                            progress=progress)
    seconds = time.perf_counter() - started
    summary = bench.score(results, design)
    settings = {"cases": len(cases), "base_seed": seed, "duration_s": args.duration,
                "design": design.name, "seconds": seconds, "quick": args.quick}
    text = bench.format_markdown(summary, results, settings)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "benchmark.json").write_text(json.dumps({"settings": settings, "summary": summary,
                                                    "results": results}, indent=1))
    (out / "benchmark.md").write_text(text)
    print()
    print(text)
    print(f"written: {out / 'benchmark.md'}, {out / 'benchmark.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
