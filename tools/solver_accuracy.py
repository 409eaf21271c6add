#!/usr/bin/env python3
"""Native accuracy of the firmware solver: the same C++ compiled with host g++ against each
design's generated header, over a million points of the joint box (plus its 64 corners and
its faces), compared with the Python reference. Prints the worst error per axis in % of full
scale, for the canonical count entry point and for the radians one.

    .venv/bin/python tools/solver_accuracy.py [designs/*.toml] [--samples 1000000]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from delta6.build.nativesolver import native_solver
from delta6.core.design import load
from delta6.core.model import AXES, ENCODER_COUNT_RAD, wrench
from delta6.core.spec import full_scale
from delta6_codegen import solver_constants

ROOT = Path(__file__).resolve().parents[1]


CHUNK = 200_000


def box_points(limit: int, samples: int, rng) -> np.ndarray:
    corners = np.array([[limit if (i >> j) & 1 else -limit for j in range(6)] for i in range(64)])
    faces = rng.integers(-limit, limit + 1, size=(6 * 2000, 6))
    faces[np.arange(len(faces)), np.arange(len(faces)) % 6] = np.where(
        np.arange(len(faces)) % 12 < 6, limit, -limit)
    return np.concatenate([corners, faces, rng.integers(-limit, limit + 1, size=(samples, 6))])


def worst(solve, inputs, to_rad, design, fs):
    err = np.zeros(6)
    for start in range(0, len(inputs), CHUNK):
        block = inputs[start:start + CHUNK]
        w, status = solve(block)
        if (status != 0).any():
            raise SystemExit(f"{design.name}: unexpected status inside the box")
        ref = wrench(design, to_rad(block))
        err = np.maximum(err, (np.abs(w - ref) / fs).max(axis=0))
    return err * 100


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("designs", nargs="*", type=Path,
                        default=sorted((ROOT / "designs").glob("*.toml")))
    parser.add_argument("--samples", type=int, default=1_000_000)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as tmp:
        for path in args.designs:
            design = load(path)
            solver = native_solver(design, Path(tmp), path.name)
            sc = solver_constants(design)
            fs = full_scale(design)
            counts = box_points(sc.limit_counts, args.samples, rng).astype(np.int16)
            err_c = worst(solver.solve_counts, counts, lambda c: c * ENCODER_COUNT_RAD, design, fs)
            theta = rng.uniform(-sc.limit_rad, sc.limit_rad, (args.samples // 5, 6))
            err_r = worst(solver.solve_radians, theta.astype(np.float32),
                          lambda t: t.astype(float), design, fs)
            print(f"{design.name:<18} counts ({len(counts):,} points): "
                  + "  ".join(f"{a} {e:.1e}" for a, e in zip(AXES, err_c)) + "  % FS")
            print(f"{'':<18} radians ({len(theta):,} points): "
                  + "  ".join(f"{a} {e:.1e}" for a, e in zip(AXES, err_r)) + "  % FS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
