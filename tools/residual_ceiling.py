#!/usr/bin/env python3
"""How much of what a unit's calibration leaves can a residual predict? Least-squares bounds.

    .venv/bin/python tools/residual_ceiling.py                 # the diagnosis picks the effects
    .venv/bin/python tools/residual_ceiling.py --effects stiffness_mismatch,joint_friction,...

The twin's `paper` scenario: a calibration run (2000 s, seed 1) and an evaluation run of the
same unit (600 s, seed 2), as tools/bench_residual.py. The unit is calibrated on the first run;
then a linear map (least squares, with a constant) from a feature set to the calibrated
model's error is fitted on the first run and applied to the second. Printed: the held-out p99
of |error| (% FS) per axis for

* `static`: the calibrated wrench and the counts (what the on-chip default sees);
* `+ causal backlash`: plus, per joint, what the encoders tell about the play: the calibrated
  model's direction, samples since the count last changed (capped at 50), the count's change
  over the 3 samples before that, its steps over 1, 2, 4 and 8 samples, and their products with
  the direction;
* `+ oracle backlash`: the static set plus, per joint, the part of the true link-minus-encoder
  angle (the twin's hidden truth) that the calibration's backlash term does not model: what any
  estimator of the link's place inside its play could at best provide.

Linear maps over these features are what the board can afford after the calibrated solve; a
small MLP on the same sets did no better on the held-out run (docs/ondevice-model.md). Each
map's share of the error's variance on the evaluation run is printed too: a map can explain
some variance and still leave the tails, which the p99 measures, where they were.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from delta6 import twin
from delta6.calibration import calibrate
from delta6.core.calibrated import CalibratedModel, counts_from_angles, sample_period
from delta6.core.design import load
from delta6.core.model import AXES
from delta6.core.spec import full_scale
from delta6.link.logfile import LogData
from delta6.twin import truth as truth_mod

ROOT = Path(__file__).resolve().parents[1]
STILL_CAP = 50


def still_and_approach(x: np.ndarray):
    """Per joint: samples since the count last changed (capped) and the count's change over
    the 3 samples up to that last change."""
    n = len(x)
    moved = np.r_[np.zeros((1, 6), bool), x[1:] != x[:-1]]
    index = np.where(moved, np.arange(n)[:, None], 0)
    last = np.maximum.accumulate(index, axis=0)
    still = np.minimum(np.arange(n)[:, None] - last, STILL_CAP)
    cols = np.arange(6)[None, :]
    approach = x[last, cols] - x[np.maximum(last - 3, 0), cols]
    return still, approach


def features(run, model: CalibratedModel, fs):
    x = counts_from_angles(run.theta)
    terms, _ = model.joint_terms(x, sample_period(run.t))
    w = model.wrench_from_terms(terms.theta, terms.torque)
    still, approach = still_and_approach(x)
    steps = [np.r_[np.zeros((k, 6)), x[k:] - x[:-k]] for k in (1, 2, 4, 8)]
    d = terms.direction
    causal = [d, still, np.clip(approach, -20, 20), *steps, d * still, d * np.clip(approach, -20, 20)]
    play_term = 0.5 * model.cal.backlash_play_rad * d
    return {"error": 100.0 * (run.wrench - w) / fs, "static": [100.0 * w / fs, x],
            "causal": causal, "gap": run.true_angles - run.theta, "play_term": play_term}


def fit_and_score(train_cols, test_cols, y_train, y_test):
    a = np.concatenate([np.c_[c] for c in train_cols] + [np.ones((len(y_train), 1))], axis=1)
    b = np.concatenate([np.c_[c] for c in test_cols] + [np.ones((len(y_test), 1))], axis=1)
    scale = np.maximum(a.std(axis=0), 1e-12)
    scale[-1] = 1.0
    coef = np.linalg.lstsq(a / scale, y_train, rcond=None)[0]
    left = y_test - (b / scale) @ coef
    # The p99 per axis, and the share of the error's variance the map explains per axis.
    return np.percentile(np.abs(left), 99, axis=0), 1.0 - left.var(axis=0) / y_test.var(axis=0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--effects", help="the effects to calibrate, comma-separated "
                                          "(default: what the diagnosis finds)")
    args = parser.parse_args()
    design = load(ROOT / "designs" / "delta6.toml")
    fs = full_scale(design)
    first = twin.simulate(design, twin.scenario_effects("paper", 1), 2000.0, seed=1,
                          scenario="paper")
    replay = truth_mod.replay_arguments(first.truth)
    replay.update(seed=2, duration_s=600.0)
    second = twin.simulate(**replay)
    started = time.perf_counter()
    effects = args.effects.split(",") if args.effects else None
    cal = calibrate(LogData(t=first.t, theta=first.theta, wrench=first.wrench), design,
                    effects=effects, name="ceiling").calibration
    print(f"calibrated ({', '.join(cal.effects)}) in {time.perf_counter() - started:.0f} s")
    model = CalibratedModel(design, cal)
    tr, te = features(first, model, fs), features(second, model, fs)
    mean_gap = tr["gap"].mean(axis=0)
    for f in (tr, te):   # what the calibration's backlash term misses, rad
        f["oracle"] = [f["gap"] - mean_gap - f["play_term"]]
    rows = {"calibrated": (np.percentile(np.abs(te["error"]), 99, axis=0), np.zeros(6))}
    for name, keys in (("+ linear map of wrench and counts (static)", ("static",)),
                       ("+ static and causal backlash features", ("static", "causal")),
                       ("+ static and oracle backlash (twin's truth)", ("static", "oracle"))):
        rows[name] = fit_and_score([c for k in keys for c in tr[k]],
                                   [c for k in keys for c in te[k]], tr["error"], te["error"])
    print("held-out p99 |error|, % FS (evaluation run, 600 s):")
    print(f"  {'':<46}" + "".join(f"{a:>7}" for a in AXES) + "   mean")
    for name, (p, _) in rows.items():
        print(f"  {name:<46}" + "".join(f"{v:7.2f}" for v in p) + f" {np.mean(p):6.2f}")
    print("share of the calibrated model's error variance each map explains (evaluation run):")
    for name, (_, explained) in list(rows.items())[1:]:
        print(f"  {name:<46}" + "".join(f"{v:7.2f}" for v in explained))
    return 0


if __name__ == "__main__":
    sys.exit(main())
