#!/usr/bin/env python3
"""Inference time of learned estimators with onnxruntime on this CPU, batch 1, window 25.

    .venv/bin/python tools/bench_learning.py build/learning/*-default.onnx [--calls 3000]

For each model: the onnxruntime call alone (one standardised window in, one standardised
wrench out) and the whole streaming step (window update, standardisation, the call, the base
model), median and 99th percentile per sample in milliseconds, on one thread.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from delta6.core.design import load
from delta6.core.paths import DEFAULT_DESIGN
from delta6.learning import LearnedEstimator


def timed(fn, calls: int) -> np.ndarray:
    for _ in range(min(200, calls)):        # warm-up: allocations, caches
        fn()
    out = np.empty(calls)
    for i in range(calls):
        start = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - start
    return out * 1e3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("models", nargs="+", type=Path, metavar="MODEL.onnx")
    parser.add_argument("--calls", type=int, default=3000)
    parser.add_argument("--design", default=str(DEFAULT_DESIGN))
    args = parser.parse_args()
    design = load(args.design)
    rng = np.random.default_rng(0)
    print(f"{'model':<28}{'params':>8}  {'onnxruntime call, ms':>22}  {'streaming step, ms':>20}")
    print(f"{'':<28}{'':>8}  {'median':>10}{'p99':>10}  {'median':>10}{'p99':>10}")
    for path in args.models:
        est = LearnedEstimator(path, design=design, threads=1)
        x = rng.normal(size=(1, est.window, 6)).astype(np.float32)
        call = timed(lambda: est.network(x), args.calls)
        live = est.streaming()
        theta = rng.uniform(-0.3, 0.3, size=(args.calls + 200, 6))
        t = np.arange(len(theta)) / est.rate_hz
        it = iter(zip(t, theta))
        step = timed(lambda: live.update(*next(it)), args.calls)
        params = est.card.training.get("parameters", 0)
        print(f"{path.name:<28}{params:>8}  {np.median(call):10.3f}{np.percentile(call, 99):10.3f}"
              f"  {np.median(step):10.3f}{np.percentile(step, 99):10.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
