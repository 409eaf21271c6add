#!/usr/bin/env python3
"""Inference time of learned estimators with onnxruntime on this CPU, batch 1, window 25.

    .venv/bin/python tools/bench_learning.py build/learning/*-default.onnx [--calls 3000]
        [--calibration CAL.toml]          # needed for hybrid models

For each model: the onnxruntime call alone (one standardised window in, one standardised
wrench out) and the whole streaming step (window update, standardisation, the call, the base
model), median and 99th percentile per sample in milliseconds of wall-clock time, and the 99th
percentile of the thread's CPU time, on one thread.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from delta6.core import calibration
from delta6.core.design import load
from delta6.core.paths import DEFAULT_DESIGN
from delta6.learning import LearnedEstimator


def timed(fn, calls: int) -> tuple[np.ndarray, np.ndarray]:
    """Wall-clock and this thread's CPU time per call, ms. On a machine shared with other jobs
    the wall-clock tail holds the time slices the scheduler gave to them; the CPU time does
    not (onnxruntime runs on the calling thread with one intra-op thread)."""
    for _ in range(min(200, calls)):        # warm-up: allocations, caches
        fn()
    wall, cpu = np.empty(calls), np.empty(calls)
    for i in range(calls):
        start, start_cpu = time.perf_counter(), time.thread_time()
        fn()
        wall[i], cpu[i] = time.perf_counter() - start, time.thread_time() - start_cpu
    return wall * 1e3, cpu * 1e3


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("models", nargs="+", type=Path, metavar="MODEL.onnx")
    parser.add_argument("--calls", type=int, default=3000)
    parser.add_argument("--design", default=str(DEFAULT_DESIGN))
    parser.add_argument("--calibration", help="the calibration of hybrid models (CAL.toml)")
    args = parser.parse_args()
    design = load(args.design)
    cal = calibration.load(args.calibration) if args.calibration else None
    rng = np.random.default_rng(0)
    print(f"{'model':<28}{'params':>8}  {'onnxruntime call, ms':>30}  {'streaming step, ms':>30}")
    print(f"{'':<28}{'':>8}  " + f"{'median':>10}{'p99':>10}{'p99 cpu':>10}" * 2)
    for path in args.models:
        est = LearnedEstimator(path, design=design, calibration=cal, threads=1)
        x = rng.normal(size=(1, est.window, 6)).astype(np.float32)
        call, call_cpu = timed(lambda: est.network(x), args.calls)
        live = est.streaming()
        theta = rng.uniform(-0.3, 0.3, size=(args.calls + 200, 6))
        t = np.arange(len(theta)) / est.rate_hz
        it = iter(zip(t, theta))
        step, step_cpu = timed(lambda: live.update(*next(it)), args.calls)
        params = est.card.training.get("parameters", 0)
        cells = [np.median(call), np.percentile(call, 99), np.percentile(call_cpu, 99),
                 np.median(step), np.percentile(step, 99), np.percentile(step_cpu, 99)]
        print(f"{path.name:<28}{params:>8}  " + "".join(f"{v:10.3f}" for v in cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
