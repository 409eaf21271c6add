#!/usr/bin/env python3
"""Blind benchmark of the gap diagnosis on fresh digital-twin scenarios.

    .venv/bin/python tools/gap_benchmark.py                 # the extended benchmark
    .venv/bin/python tools/gap_benchmark.py --quick         # a few cases of each kind
    .venv/bin/python tools/gap_benchmark.py --seed 123 --out results/
    .venv/bin/python tools/gap_benchmark.py --rescore results/benchmark.json

Prints progress, the figures (top-1 on single effects, false positives, pairs, parameter
recovery, predicted vs true shrink, run time), the confusion matrix and the paper scenario's
ladder; writes benchmark.json and benchmark.md into --out. ``--rescore`` takes an earlier
run's benchmark.json, measures the joints each unknown per-joint effect bends with today's
measure (simulating those cases again) and prints the unknown effects' figures both ways.
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
    parser.add_argument("--seed", type=int, default=None,
                        help="base seed (default: the documented run's, in docs/diagnosis.md)")
    parser.add_argument("--duration", type=float, default=400.0, help="seconds per run")
    parser.add_argument("--pairs", type=int, default=4)
    parser.add_argument("--none", type=int, default=4, dest="n_none")
    parser.add_argument("--mixes", type=int, default=12, help="mixes of 4..8 effects")
    parser.add_argument("--axis-mixes", type=int, default=3,
                        help="mixes under one-axis-at-a-time excitation")
    parser.add_argument("--unknown", type=int, default=3,
                        help="runs per effect withheld from the diagnosis's families")
    parser.add_argument("--paper", action="store_true", help="add the paper scenario (2000 s)")
    parser.add_argument("--quick", action="store_true",
                        help="a few cases of each kind (development, not the figures)")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", default=str(ROOT / "build" / "gap-benchmark"))
    parser.add_argument("--rescore", metavar="BENCHMARK_JSON",
                        help="re-score an earlier run's records (see above) and stop")
    args = parser.parse_args()

    from delta6.core.design import load
    from delta6.evaluation import gap_benchmark as bench

    if args.rescore:
        return rescore(bench, Path(args.rescore), args.design)

    seed = bench.DEFAULT_BASE_SEED if args.seed is None else args.seed
    if args.quick:
        cases = bench.plan(seed, magnitudes=(0.8,), n_pairs=2, n_none=2, paper=False,
                           n_mixes=3, n_axis_mixes=1, unknown_per_effect=1)
    else:
        cases = bench.plan(seed, magnitudes=(0.75,), n_pairs=args.pairs, n_none=args.n_none,
                           paper=args.paper, n_mixes=args.mixes, n_axis_mixes=args.axis_mixes,
                           axis_singles=True, unknown_per_effect=args.unknown)
    design = load(args.design)
    print(f"gap benchmark: {len(cases)} blind cases, {args.duration:g} s each, "
          f"{args.jobs} jobs, base seed {seed}", flush=True)

    def progress(done, total, r):
        truth = ", ".join(f"{t['name']}/{t['formulation']}" for t in r["truth"]) or r["kind"]
        named = set(r["present"]) | {m for g in r["groups"] for m in g["members"]}
        mark = "ok " if ({t["name"] for t in r["truth"]} <= named
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


def rescore(bench, path: Path, design_path: str) -> int:
    try:
        payload = json.loads(path.read_text())
        results, duration = payload["results"], float(payload["settings"]["duration_s"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"error: {path}: not a gap benchmark's benchmark.json ({exc})", file=sys.stderr)
        return 2
    try:
        added = bench.add_bends(results, design_path, duration)
        summary = bench.score_extended(results)
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        print(f"error: {path}: a record is not a gap benchmark's ({type(exc).__name__}: "
              f"{exc})", file=sys.stderr)
        return 2
    print(f"{path}: bends measured for {added} unknown per-joint runs; "
          f"seed {payload['settings'].get('base_seed')}")
    print(f"unknown effects: leftover right {summary['unknown_leftover_ok']:.0%} of "
          f"{summary['unknown_runs']} on the joints the effect bends, "
          f"{summary['unknown_leftover_ok_every_joint']:.0%} on every joint it acts on")
    for r in results:
        t = r["truth"][0] if r["kind"] == "unknown" else None
        if t and "leftover_joints" in t:
            bends = ", ".join(f"j{j} {1e3 * t['beyond_line_nm'][j - 1]:.3f}" for j in t["joints"])
            print(f"  {r['case']['seed']} {t['name']}: bends (mN*m) {bends} -> expected "
                  f"{t['leftover_joints']}, found {r['leftover']['joints']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
