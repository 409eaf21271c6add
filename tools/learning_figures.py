#!/usr/bin/env python3
"""The learned estimators' figures (docs/learning.md): Table V on the twin's `paper` scenario,
the learning curve and the second unit.

    .venv/bin/python tools/learning_figures.py [--out build/learning] [--budget-minutes 8]

Simulates a 2000 s calibration run of one unit (the `paper` scenario, seed 1), a 600 s
evaluation run of the SAME unit (its effects replayed from the truth record with a new
trajectory, noise and temperature: seed 2, what `delta6 simulate --unit` does) and a 600 s run
of a SECOND unit (the same effects, each redrawn at magnitude 0.75 from its own seed).
Calibrates the unit on the calibration run (`delta6 calibrate`), trains every model (default and
paper presets end-to-end, and the default MLP as a residual over the analytical model and over
the calibration: the hybrid), evaluates them on both runs, repeats the calibration, the best
end-to-end default model, the residual MLP and the hybrid on the first 200 s and 500 s of the calibration run (the
learning curve), and writes `results.json` and `tables.md`. Models and calibrations already in
the output folder are reused (delete them to retrain).
``--budget-minutes`` bounds the wall-clock training time of each model (the best checkpoint so
far is kept; the tables say when a budget stopped a model).

``--only calibration-rows`` recomputes just the rows that depend on the calibration fit (the
calibrated model and the hybrid, on the learning curve and on the second unit) with the same
runs, seeds and prefixes, and writes `calibration-rows.json` and `calibration-rows.md`: what to
re-run when the calibration's fit changes (delete the folder's `unit1-*s.toml` and
`mlp-hybrid-default*.onnx` first, or they are reused).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from delta6 import twin
from delta6.core import accuracy
from delta6.core import calibration as calibration_mod
from delta6.core.calibrated import CalibratedModel
from delta6.core.design import load
from delta6.core.model import AXES
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.spec import full_scale
from delta6.learning import LearnedEstimator
from delta6.link.logfile import LogData, read_log

SECOND_UNIT_SEED = 77
SECOND_UNIT_MAGNITUDE = 0.75
CURVE_SECONDS = (200, 500, 2000)


def runs(design, out: Path) -> dict[str, Path]:
    paths = {"cal": out / "unit1-cal-2000s.csv", "same": out / "unit1-eval-600s.csv",
             "second": out / "unit2-eval-600s.csv"}
    if all(p.exists() for p in paths.values()):
        return paths
    cal = twin.simulate(design, twin.scenario_effects("paper", seed=1), duration_s=2000, seed=1,
                        scenario="paper")
    twin.write_log(cal, paths["cal"])
    same = twin.simulate(design, twin.effects_from_truth(cal.truth), duration_s=600, seed=2,
                         scenario="paper")
    twin.write_log(same, paths["same"])
    second_effects = [twin.make_effect(e["name"], SECOND_UNIT_SEED, formulation=e["formulation"],
                                       magnitude=SECOND_UNIT_MAGNITUDE)
                      for e in cal.truth["effects"]]
    second = twin.simulate(design, second_effects, duration_s=600, seed=3)
    twin.write_log(second, paths["second"])
    return paths


def head(log: LogData, seconds: float) -> LogData:
    keep = log.t - log.t[0] < seconds
    return LogData(t=log.t[keep], theta=log.theta[keep], wrench=log.wrench[keep], meta=log.meta)


def calibration_of(log: LogData, design, seconds: int, out: Path):
    """The unit's calibration fitted on the first ``seconds`` of the calibration run."""
    from delta6.calibration import calibrate

    path = out / f"unit1-{seconds}s.toml"
    if not path.exists():
        started = time.perf_counter()
        fitted = calibrate(head(log, seconds), design, name=f"unit1-{seconds}s")
        calibration_mod.save(fitted.calibration, path)
        print(f"  calibration on {seconds} s: {time.perf_counter() - started:.0f} s",
              file=sys.stderr)
    return calibration_mod.load(path)


def train_one(name: str, log: LogData, design, kind: str, preset_name: str, base: str,
              out: Path, budget: float | None, calibration=None) -> Path:
    from delta6.learning import fit
    from delta6.learning.presets import preset

    path = out / f"{name}.onnx"
    if path.exists():
        return path
    chosen = preset(preset_name, kind)
    if budget:
        chosen = chosen.with_recipe(max_minutes=budget)
    started = time.perf_counter()

    def progress(r):
        print(f"\r  {name}: epoch {r.epoch}/{r.max_epochs} held-out {r.holdout_loss:.5f} "
              f"(best {r.best_loss:.5f} @ {r.best_epoch}) {r.seconds:.0f} s", end="",
              file=sys.stderr, flush=True)

    fitted = fit.fit(log, design, chosen, base=base, calibration=calibration, seed=0, threads=1,
                     source=name, progress=progress)
    fit.write(fitted, path)
    print(f"\r  {name}: {fitted.trained.stopped}, {time.perf_counter() - started:.0f} s"
          + " " * 30, file=sys.stderr, flush=True)
    return path


def hybrid_model(cal: LogData, design, seconds: int, out: Path, budget: float | None,
                 calibration) -> Path:
    """The default MLP trained as a residual over ``calibration`` on the first ``seconds`` of the
    calibration run (the whole run for the longest)."""
    whole = seconds == CURVE_SECONDS[-1]
    return train_one("mlp-hybrid-default" if whole else f"mlp-hybrid-default-{seconds}s",
                     cal if whole else head(cal, seconds), design, "mlp", "default",
                     "calibration", out, budget, calibration)


def calibration_rows(cal: LogData, same: LogData, second: LogData, design, fs, out: Path,
                     budget: float | None) -> dict:
    """The calibrated model and the hybrid fitted on each prefix of the calibration run, on the
    same unit's evaluation run (the learning curve) and, for the whole run, on the second unit."""
    results = {"full_scale": fs.tolist(), "curve": [], "second_unit": []}
    for seconds in CURVE_SECONDS:
        calibration = calibration_of(cal, design, seconds, out)
        hybrid = LearnedEstimator(hybrid_model(cal, design, seconds, out, budget, calibration),
                                  design=design, calibration=calibration)
        for name, predict in (("calibrated", CalibratedModel(design, calibration).predict),
                              ("mlp-hybrid-default", hybrid.predict)):
            results["curve"].append({"estimator": name, "seconds": seconds,
                                     **row(predict(same), same, fs)})
            if seconds == CURVE_SECONDS[-1]:
                results["second_unit"].append({"estimator": name,
                                               **row(predict(second), second, fs)})
    return results


def calibration_tables(results: dict) -> str:
    lines = ["Calibration-dependent rows, % FS (p99 | max)", "",
             "| estimator | run | unit | p99 " + " | ".join(AXES) + " | max "
             + " | ".join(AXES) + " |", "|---|---|---|" + "---|" * 12]
    for unit, rows in (("same", results["curve"]), ("second", results["second_unit"])):
        for r in rows:
            seconds = r.get("seconds", CURVE_SECONDS[-1])
            lines.append(f"| {r['estimator']} | {seconds} s | {unit} | "
                         + " | ".join(f"{v:.2f}" for v in r["p99_pct"] + r["max_pct"]) + " |")
    return "\n".join(lines) + "\n"


def row(estimate, log: LogData, fs) -> dict:
    t = accuracy.percentiles(estimate, log.wrench, fs, (95, 99, 100))
    return {"p95_pct": t["p95"], "p99_pct": t["p99"], "max_pct": t["p100"]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="build/learning", type=Path)
    parser.add_argument("--budget-minutes", type=float, default=8.0)
    parser.add_argument("--skip-paper", action="store_true", help="default presets only")
    parser.add_argument("--only", choices=("calibration-rows",),
                        help="recompute only the calibrated and hybrid rows of the learning "
                             "curve and the second unit")
    args = parser.parse_args()
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    design = load(DEFAULT_DESIGN)
    fs = full_scale(design)
    paths = runs(design, out)
    cal, same, second = (read_log(paths[k]) for k in ("cal", "same", "second"))
    if args.only == "calibration-rows":
        results = calibration_rows(cal, same, second, design, fs, out, args.budget_minutes)
        (out / "calibration-rows.json").write_text(json.dumps(results, indent=1))
        (out / "calibration-rows.md").write_text(calibration_tables(results))
        print(calibration_tables(results))
        return 0

    specs = [(f"{kind}-default", kind, "default", "none") for kind in
             ("mlp", "gru", "lstm", "transformer")]
    specs.append(("mlp-residual-default", "mlp", "default", "analytical"))
    if not args.skip_paper:
        specs += [(f"{kind}-paper", kind, "paper", "none") for kind in
                  ("transformer", "lstm", "gru", "mlp")]
    models = {}
    for name, kind, preset_name, base in specs:
        models[name] = train_one(name, cal, design, kind, preset_name, base, out,
                                 args.budget_minutes)
    calibrations = {seconds: calibration_of(cal, design, seconds, out)
                    for seconds in CURVE_SECONDS}
    unit_cal = calibrations[2000]
    models["mlp-hybrid-default"] = hybrid_model(cal, design, CURVE_SECONDS[-1], out,
                                                args.budget_minutes, unit_cal)

    from delta6.core.model import wrench
    results = {"full_scale": fs.tolist(), "same_unit": [], "second_unit": [], "curve": [],
               "models": {}}
    calibrated = CalibratedModel(design, unit_cal)
    for key, log in (("same_unit", same), ("second_unit", second)):
        results[key].append({"estimator": "analytical", **row(wrench(design, log.theta), log, fs)})
        results[key].append({"estimator": "calibrated", **row(calibrated.predict(log), log, fs)})
    for name, path in models.items():
        est = LearnedEstimator(path, design=design, calibration=unit_cal)
        results["models"][name] = {"card": est.card.training, "hyper": est.card.hyperparameters,
                                   "base": est.card.base}
        for key, log in (("same_unit", same), ("second_unit", second)):
            results[key].append({"estimator": name, **row(est.predict(log), log, fs)})

    end_to_end = [r for r in results["same_unit"] if r["estimator"] in models
                  and r["estimator"].endswith("-default")
                  and results["models"][r["estimator"]]["base"] == "none"]
    best = min(end_to_end, key=lambda r: max(r["p99_pct"]))["estimator"]
    results["best_end_to_end"] = best
    for seconds in CURVE_SECONDS:
        results["curve"].append({"estimator": "calibrated", "seconds": seconds, **row(
            CalibratedModel(design, calibrations[seconds]).predict(same), same, fs)})
    for name in (best, "mlp-residual-default", "mlp-hybrid-default"):
        kind = name.split("-")[0]
        base = results["models"][name]["base"]
        for seconds in CURVE_SECONDS:
            path = models[name] if seconds == 2000 else train_one(
                f"{name}-{seconds}s", head(cal, seconds), design, kind, "default", base, out,
                args.budget_minutes, calibrations[seconds])
            est = LearnedEstimator(path, design=design, calibration=calibrations[seconds])
            results["curve"].append({"estimator": name, "seconds": seconds,
                                     **row(est.predict(same), same, fs)})
    (out / "results.json").write_text(json.dumps(results, indent=1))
    (out / "tables.md").write_text(tables(results))
    print(tables(results))
    return 0


def tables(results: dict) -> str:
    head_ = "| estimator | pct | " + " | ".join(AXES) + " |\n|---|---|" + "---|" * 6 + "\n"
    lines = []

    def table(rows, title):
        lines.append(f"\n{title}\n\n" + head_.rstrip("\n"))
        for r in rows:
            for key, label in (("max_pct", "max"), ("p99_pct", "p99"), ("p95_pct", "p95")):
                lines.append(f"| {r['estimator']} | {label} | "
                             + " | ".join(f"{v:.2f}" for v in r[key]) + " |")

    table(results["same_unit"], "Same unit, 600 s evaluation run (% FS)")
    table(results["second_unit"], "Second unit, 600 s run, models trained on the first (% FS)")
    lines.append("\nLearning curve: p99 % FS on the same unit's evaluation run\n")
    lines.append("| estimator | calibration run | " + " | ".join(AXES) + " |\n|---|---|"
                 + "---|" * 6)
    for r in results["curve"]:
        lines.append(f"| {r['estimator']} | {r['seconds']} s | "
                     + " | ".join(f"{v:.2f}" for v in r["p99_pct"]) + " |")
    lines.append("\nTraining (2000 s run)\n\n| model | parameters | epochs | best | stopped | "
                 "seconds |\n|---|---|---|---|---|---|")
    for name, m in results["models"].items():
        c = m["card"]
        lines.append(f"| {name} | {c['parameters']} | {c['epochs']} | {c['best_epoch']} | "
                     f"{c['stopped']} | {c['seconds']:.0f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
