"""Calibration benchmark: the figures of docs/calibration.md.

    .venv/bin/python tools/bench_calibration.py                   # everything, ~30 min
    .venv/bin/python tools/bench_calibration.py --quick           # shorter runs, ~5 min
    .venv/bin/python tools/bench_calibration.py --sections paper,board,sizes
    .venv/bin/python tools/bench_calibration.py --sections paper --rig-latency 0.01

Sections (each prints a Markdown table):

- ``paper``: the twin's ``paper`` scenario, a 2000 s calibration run (seed 1) and a 600 s
  evaluation run of the same unit (seed 2, ``twin.same_unit``): ``delta6 calibrate`` (timed:
  10^5 samples) and Table V of the analytical and the calibrated model (Python) on the
  evaluation run: against its recorded reference (late by the rig's 10 ms, the paper's
  Table V), against that reference advanced by the fitted rig latency (``delta6 evaluate
  --rig-latency calibration``), and against the same run re-simulated without the rig's
  delay (``twin.without(truth, ["sensor_latency"])``: the true wrench); then the same unit
  calibrated on half as long a log of pushes one axis at a time (seed 5): its held-out
  table and its Table V on the evaluation run.
- ``board``: the same unit's evaluation run at the board's rate, replayed through the
  calibrated firmware on the virtual board (emulated ATmega328P, 16 MHz): Table V of the
  streamed wrench, the Python calibrated model on the counts the board latched, the largest
  difference between the two, and the cycles per sample; then a short rate sweep for overruns.
- ``sizes``: flash and RAM of the ATmega328P image and the avrxmega3 size check, with and
  without the calibration.
- ``effects``: each correctable effect's single-effect scenario (``--effects`` picks some):
  calibrated p99 on an unseen run of the same unit against what the diagnosis predicted would
  be left on the chip (its final model refitted with a board's causal features, held out:
  ``on_chip``; its offline figure beside it), and the twin's floor (the same run without the
  effect). ``--effect-seeds N`` repeats it on N units and runs (calibration run on seed s,
  unseen run on s + 1) and adds the unseen run's own on-chip figure: how much a 600 s run's
  p99 moves with its motion.
  An effect without a scenario of its own (the curves) is the twin's effect alone at its
  default (mid-range) magnitude.
- ``curves``: the paper unit's calibration with and without both curve tables (a spring
  stiffening by 12 % at 0.5 rad, a magnet's error of 0.015 rad in the first harmonic falling
  as 1/h): flash and RAM of the ATmega328P image, the avrxmega3 size check, and the cycles per
  sample on the emulated ATmega328P streaming at 200 Hz (the curved image's rated rate); then
  the worst case of both images at 200, 225 and 250 Hz: every joint moving and reversing
  every sample (counts alternating by 1 and by 12 on every joint: the reversal's backlash
  multiply, unsaturated plays, and steps beyond the speed filter's table), wrench+raw.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from delta6 import twin
from delta6.build import appbuild
from delta6.calibration import calibrate
from delta6.commands.codegen import design_firmware
from delta6.core import accuracy
from delta6.core import calibration as C
from delta6.core.calibrated import CalibratedModel
from delta6.core.calibration import CORRECTED
from delta6.core.model import AXES, ENCODER_COUNT_RAD
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.spec import full_scale
from delta6.core.workspace import load_checked
from delta6.diagnosis.run import diagnose
from delta6.evaluation import tablev
from delta6.evaluation.boardstream import stream_log
from delta6.twin.pushes import AxisPushes
from delta6.twin.streams import stream

HEADER = "| | " + " | ".join(AXES) + " |\n|---|" + "---|" * 6


def row(label, values) -> str:
    return f"| {label} | " + " | ".join(f"{v:.2f}" for v in values) + " |"


def tv(estimate, reference, fs) -> dict:
    return accuracy.percentiles(estimate, reference, fs, (95, 99, 100))


def table_lines(label, t) -> list[str]:
    return [row(f"{label} p95", t["p95"]), row(f"{label} p99", t["p99"]),
            row(f"{label} max", t["p100"])]


def from_file(t) -> dict:
    """A calibration file's table (p95_pct, p99_pct, max_pct) in ``tv``'s keys."""
    return {"p95": t["p95_pct"], "p99": t["p99_pct"], "p100": t["max_pct"]}


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def section_paper(design, args, out, tmp) -> dict:
    effects = twin.scenario_effects("paper", seed=1)
    cal_run = twin.simulate(design, effects, duration_s=args.cal_duration, rate_hz=50, seed=1,
                            scenario="paper")
    wall, cpu = time.perf_counter(), cpu_seconds()
    fit = calibrate(cal_run, design, name="paper-unit", source="paper seed 1",
                    rig_latency_s=args.rig_latency)
    wall, cpu = time.perf_counter() - wall, cpu_seconds() - cpu
    path = C.save(fit.calibration, tmp / "paper-unit.toml")
    check = twin.simulate(duration_s=args.eval_duration, rate_hz=50,
                          **twin.same_unit(cal_run.truth, 2))
    fs = full_scale(design)
    model = CalibratedModel(design, fit.calibration)
    estimate, plain = model.predict(check), check.model_wrench()
    analytical = tv(plain, check.wrench, fs)
    calibrated = tv(estimate, check.wrench, fs)
    advanced, keep = tablev.advanced_reference(check, fit.latency_s)
    analytical_adv = tv(plain[keep], advanced, fs)
    calibrated_adv = tv(estimate[keep], advanced, fs)
    prompt = twin.simulate(**twin.without(check.truth, ["sensor_latency"]))
    analytical_true = tv(prompt.model_wrench(), prompt.wrench, fs)
    calibrated_true = tv(model.predict(prompt), prompt.wrench, fs)
    # Another excitation: the paper's Fig. 9 style (slow pushes along one axis at a time, long
    # holds), the same unit, a motion the calibration run never made.
    unit = twin.same_unit(cal_run.truth, 3)
    pushes = twin.simulate(duration_s=args.eval_duration, rate_hz=50,
                           path=AxisPushes(design, args.eval_duration, stream(3, "pushes")),
                           **unit)
    analytical_push = tv(pushes.model_wrench(), pushes.wrench, fs)
    calibrated_push = tv(model.predict(pushes), pushes.wrench, fs)
    # The other way round: calibrated on a log that loads one axis at a time (weights hung
    # axis by axis), half as long; its own held-out table, and the random evaluation run.
    push_s = args.cal_duration / 2
    push_run = twin.simulate(duration_s=push_s, rate_hz=50,
                             path=AxisPushes(design, push_s, stream(5, "pushes")),
                             **twin.same_unit(cal_run.truth, 5))
    push_fit = calibrate(push_run, design, name="paper-unit-pushes", source="pushes seed 5",
                         rig_latency_s=args.rig_latency)
    push_on_check = tv(CalibratedModel(design, push_fit.calibration).predict(check),
                       check.wrench, fs)
    cal = fit.calibration
    ladder = fit.diagnosis["ladder"]
    predicted_offline = (ladder[-1]["refit_heldout_p99_pct"] if ladder
                         else fit.diagnosis["baseline_heldout_p99_pct"])
    predicted_on_chip = fit.diagnosis["on_chip"]["heldout_p99_pct"]
    lines = [f"### paper: calibrated on {len(cal_run)} samples ({args.cal_duration:g} s), "
             f"evaluated on {len(check)} ({args.eval_duration:g} s, same unit, seed 2)", "",
             f"`delta6 calibrate`: {wall:.1f} s wall, {cpu:.1f} s CPU; corrects "
             f"{', '.join(cal.effects)}; rig latency {1e3 * fit.latency_s:.2f} ms; viscous "
             f"{' '.join(f'{v:.5f}' for v in cal.viscous_nm_s_per_rad)} N*m*s/rad; sign levels "
             f"{np.round(cal.friction_sign_nm, 4).tolist()} N*m", "",
             "The diagnosis's prediction, held out on the calibration run, p99 % FS: offline "
             + " ".join(f"{v:.2f}" for v in predicted_offline) + "; on the chip "
             + (" ".join(f"{v:.2f}" for v in predicted_on_chip)
                if predicted_on_chip is not None else "-"), "", HEADER,
             *table_lines("analytical", analytical), *table_lines("calibrated", calibrated),
             *table_lines("analytical, reference advanced by the fitted latency",
                          analytical_adv),
             *table_lines("calibrated, reference advanced by the fitted latency",
                          calibrated_adv),
             *table_lines("analytical, the run without the rig's delay", analytical_true),
             *table_lines("calibrated, the run without the rig's delay", calibrated_true),
             *table_lines("analytical, one axis at a time (pushes and holds, seed 3)",
                          analytical_push),
             *table_lines("calibrated, one axis at a time (pushes and holds, seed 3)",
                          calibrated_push),
             "", f"Calibrated on {push_s:g} s of pushes one axis at a time (seed 5): "
             f"corrects {', '.join(push_fit.calibration.effects)}; its held-out blocks, then "
             "the evaluation run above:", "", HEADER,
             *table_lines("analytical, its held-out blocks", from_file(push_fit.heldout_before)),
             *table_lines("calibrated, its held-out blocks", from_file(push_fit.heldout_after)),
             *table_lines("calibrated on pushes, the evaluation run", push_on_check),
             *(f"note: {n}" for n in push_fit.notes if n.startswith("held-out "))]
    print("\n".join(lines) + "\n", flush=True)
    out["paper"] = {"calibrate_wall_s": wall, "calibrate_cpu_s": cpu,
                    "effects": list(cal.effects), "analytical": analytical,
                    "calibrated": calibrated, "samples": len(cal_run),
                    "rig_latency_s": fit.latency_s,
                    "viscous_nm_s_per_rad": cal.viscous_nm_s_per_rad.tolist(),
                    "analytical_advanced": analytical_adv, "calibrated_advanced": calibrated_adv,
                    "analytical_without_delay": analytical_true,
                    "calibrated_without_delay": calibrated_true,
                    "analytical_pushes": analytical_push, "calibrated_pushes": calibrated_push,
                    "calibrated_on_pushes": {"heldout_before": push_fit.heldout_before,
                                             "heldout_after": push_fit.heldout_after,
                                             "evaluation": push_on_check},
                    "predicted_offline": predicted_offline,
                    "predicted_on_chip": predicted_on_chip}
    return {"truth": cal_run.truth, "calibration": fit.calibration, "path": path,
            "latency_s": fit.latency_s}


def section_board(design, args, out, unit) -> None:
    check = twin.simulate(duration_s=args.eval_duration, rate_hz=args.board_rate,
                          **twin.same_unit(unit["truth"], 2))
    image = design_firmware(Path(DEFAULT_DESIGN), unit["path"])
    started = time.perf_counter()
    run = stream_log(image, check, rate_hz=args.board_rate, seconds=args.board_seconds,
                     progress=lambda m: print(f"  {m}", file=sys.stderr, flush=True))
    fs = full_scale(design)
    python, _ = CalibratedModel(design, unit["calibration"]).run(run.delta,
                                                                 1.0 / args.board_rate)
    moving = run.rows >= 0
    ref = check.wrench[run.rows[moving]]
    board = tv(run.wrench[moving], ref, fs)
    host = tv(python[moving], ref, fs)
    analytical = tv(check.model_wrench()[run.rows[moving]], ref, fs)
    advanced, keep = tablev.advanced_reference(check, unit["latency_s"])
    index = np.full(len(check), -1)
    index[np.flatnonzero(keep)] = np.arange(keep.sum())
    late = moving & (index[np.maximum(run.rows, 0)] >= 0)
    board_adv = tv(run.wrench[late], advanced[index[run.rows[late]]], fs)
    diff = float((np.abs(run.wrench - python) / fs * 100).max())
    t = run.stats["timing"]
    lines = [f"### board: {moving.sum()} records at {args.board_rate} Hz "
             f"({time.perf_counter() - started:.0f} s wall), the unit's seed-2 run", "",
             HEADER, *table_lines("analytical", analytical),
             *table_lines("calibrated, streamed by the board", board),
             *table_lines("calibrated, Python on the board's counts", host),
             *table_lines("calibrated, streamed by the board, reference advanced by the "
                          "fitted latency", board_adv), "",
             f"largest |board - Python| {diff:.4f} % FS; records paired with their log row: "
             f"{100 * run.matched:.1f} %", "",
             f"solve {t['solve_cycles']['mean']:.0f} cycles mean, {t['solve_cycles']['max']:.0f}"
             f" max; whole sample {t['process_cycles']['mean']:.0f} mean; missed periods "
             f"{t['missed_ticks']} of {t['samples'] + t['missed_ticks']}; CPU "
             f"{100 * t['cpu_busy']:.0f} % busy"]
    sweep = []
    # The same image without its rated maxima, so that the board accepts rates beyond them.
    unrated = design_firmware(Path(DEFAULT_DESIGN), unit["path"],
                              defines=["DELTA6_MAX_RATE_HZ=2000",
                                       "DELTA6_MAX_RATE_PIPELINE_HZ=2000"])
    for rate in args.sweep:
        short = twin.simulate(duration_s=4, rate_hz=rate, **twin.same_unit(unit["truth"], 3))
        r = stream_log(unrated, short, rate_hz=rate, hold_s=2.0)
        tt = r.stats["timing"]
        sweep.append({"rate": rate, "missed": tt["missed_ticks"], "samples": tt["samples"],
                      "busy": tt["cpu_busy"], "solve": tt["solve_cycles"]["mean"]})
        lines.append(f"- {rate} Hz: {tt['missed_ticks']} missed periods of "
                     f"{tt['samples'] + tt['missed_ticks']}, CPU {100 * tt['cpu_busy']:.0f} % busy")
    print("\n".join(lines) + "\n", flush=True)
    out["board"] = {"rate_hz": args.board_rate, "records": int(moving.sum()),
                    "analytical": analytical, "board": board, "python": host,
                    "board_advanced": board_adv,
                    "max_board_python_pct": diff, "timing": t, "sweep": sweep}


def section_sizes(design, args, out, unit) -> None:
    plain = design_firmware(Path(DEFAULT_DESIGN))
    calibrated = design_firmware(Path(DEFAULT_DESIGN), unit["path"])
    include_plain = plain.elf.parent.parent / "include"
    include_cal = calibrated.elf.parent.parent / "include"
    probe_plain = appbuild.size_check_app("avrxmega3", include_plain, name="probe-plain")
    probe_cal = appbuild.size_check_app("avrxmega3", include_cal, name="probe-calibrated")
    lines = ["### sizes (bytes)", "", "| image | flash | static RAM |", "|---|---|---|"]
    sizes = {}
    for label, image in (("ATmega328P, analytical", plain), ("ATmega328P, calibrated", calibrated),
                         ("avrxmega3 check, analytical", probe_plain),
                         ("avrxmega3 check, calibrated", probe_cal)):
        lines.append(f"| {label} | {image.sizes.flash} | {image.sizes.ram} |")
        sizes[label] = {"flash": image.sizes.flash, "ram": image.sizes.ram}
    print("\n".join(lines) + "\n", flush=True)
    out["sizes"] = sizes


def section_effects(design, args, out, tmp) -> None:
    fs = full_scale(design)
    lines = ["### single effects: calibrated p99 on an unseen run vs the diagnosis's prediction",
             "", "| effect | seed | chosen | rig latency fitted, ms | floor p99 (max axis) "
             "| analytical p99 | predicted p99, offline | predicted p99, on the chip "
             "| calibrated p99 | ratio to on-chip (min..max) | worst ratio to offline "
             "| within 25 % | the unseen run's own on-chip / the prediction (min..max) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    rows = []
    seeds = range(1, args.effect_seeds + 1)
    for name in args.effects or CORRECTED:
        for seed in seeds:
            rows.append(_effect_row(design, fs, name, seed, args, lines))
    print("\n".join(lines) + "\n", flush=True)
    if args.effect_seeds > 1:
        summary = ["### single effects over seeds 1.." + str(args.effect_seeds)
                   + ": the calibration run on seed s, the unseen run on seed s + 1", "",
                   "| effect | within 25 % | worst ratio to the on-chip prediction, per seed "
                   "| the unseen run's own on-chip / the prediction, worst axis, per seed |",
                   "|---|---|---|---|"]
        for name in args.effects or CORRECTED:
            mine = [r for r in rows if r["effect"] == name]
            summary.append(
                f"| {name} | {sum(r['ok'] for r in mine)} of {len(mine)} | "
                + " ".join(f"{max(r['ratio']):.2f}" for r in mine) + " | "
                + " ".join(f"{max(r['unseen_on_chip_ratio']):.2f}" for r in mine) + " |")
        print("\n".join(summary) + "\n", flush=True)
    out["effects"] = rows


def _effect_row(design, fs, name, seed, args, lines) -> dict:
    scenario = name if name in twin.SCENARIOS else None
    effects = twin.scenario_effects(name, seed=seed) if scenario \
        else [twin.make_effect(name, seed)]
    cal_run = twin.simulate(design, effects, duration_s=args.cal_duration, rate_hz=50,
                            seed=seed, scenario=scenario)
    fit = calibrate(cal_run, design, name=f"{name[:14]}-unit")
    # The diagnosis's final refit, undamped: one set of parameters, as a calibration is
    # (the ladder's damped figure blends refits per axis); offline, and with the features
    # and families a board applies (``diagnosis.onchip``): the prediction a calibration
    # on the chip is held to.
    baseline = fit.diagnosis["baseline_heldout_p99_pct"]
    offline = np.asarray(fit.diagnosis["ladder"][-1]["refit_heldout_p99_pct"]
                         if fit.diagnosis["ladder"] else baseline)
    on_chip = fit.diagnosis["on_chip"]["heldout_p99_pct"]
    predicted = np.asarray(baseline if on_chip is None else on_chip)
    check = twin.simulate(duration_s=args.eval_duration, rate_hz=50,
                          **twin.same_unit(cal_run.truth, seed + 1))
    floor_run = twin.simulate(**twin.without(check.truth, [name]))
    floor = np.asarray(floor_run.gap((99,))["p99"])
    got = np.asarray(tv(CalibratedModel(design, fit.calibration).predict(check),
                        check.wrench, fs)["p99"])
    analytical = np.asarray(tv(check.model_wrench(), check.wrench, fs)["p99"])
    # How far the unseen run itself differs: the diagnosis's on-chip figure on it (its own
    # held-out folds) against the calibration run's; the p99 of a 600 s run moves with its
    # motion whatever the correction.
    own = diagnose(check, design)["on_chip"]["heldout_p99_pct"]
    own = np.asarray(baseline if own is None else own)
    ratio = got / predicted
    # Within 25 %: the calibration leaves at most a quarter more than predicted.
    ok = bool(np.all(ratio <= 1.25))
    lines.append(f"| {name} | {seed} | {', '.join(fit.calibration.effects) or '-'} | "
                 f"{1e3 * fit.latency_s:.2f} | {floor.max():.2f} | "
                 f"{' '.join(f'{v:.2f}' for v in analytical)} | "
                 f"{' '.join(f'{v:.2f}' for v in offline)} | "
                 f"{' '.join(f'{v:.2f}' for v in predicted)} | "
                 f"{' '.join(f'{v:.2f}' for v in got)} | "
                 f"{ratio.min():.2f}..{ratio.max():.2f} | {(got / offline).max():.2f} | "
                 f"{'yes' if ok else 'NO'} | "
                 f"{(own / predicted).min():.2f}..{(own / predicted).max():.2f} |")
    print(lines[-1], file=sys.stderr, flush=True)
    return {"effect": name, "seed": seed, "chosen": list(fit.calibration.effects),
            "rig_latency_s": fit.latency_s, "floor": floor.tolist(),
            "analytical": analytical.tolist(), "predicted": predicted.tolist(),
            "predicted_offline": offline.tolist(), "calibrated": got.tolist(),
            "ratio": ratio.tolist(), "ok": ok,
            "unseen_on_chip": own.tolist(),
            "unseen_on_chip_ratio": (own / predicted).tolist()}


def with_example_curves(cal: C.Calibration) -> C.Calibration:
    """``cal`` with a spring stiffening by 12 % of the nominal torque at the reference (the
    twin's cubic spring at the top of its range) and a magnet's error of 0.015 rad in the first
    harmonic falling as 1/h (any phase: 0.7 h rad)."""
    h = np.repeat(np.arange(1, 5), 2)
    phase = np.where(np.arange(8) % 2 == 0, np.cos(0.7 * h), np.sin(0.7 * h))
    return cal.with_(name=(cal.name[:16] + "-curves"),
                     effects=tuple(cal.effects) + ("nonlinear_spring", "encoder_periodic_error"),
                     spring_curvature=np.tile([0.0, 0.12], (6, 1)),
                     encoder_periodic_rad=np.tile(0.015 / h * phase, (6, 1)))


WORST_RATES_HZ = (200, 225, 250)
UNRATED = ("DELTA6_MAX_RATE_HZ=2000", "DELTA6_MAX_RATE_PIPELINE_HZ=2000")
WORST_AMPLITUDES = (1, 12)


def alternating_counts(rate_hz: int, amplitude: int, seconds: float = 6.0):
    """A log (``t``, ``theta``) the board samples as every joint moving and reversing every
    period: each joint's count alternates between a pose inside the box and ``amplitude``
    counts from it (in opposite directions on neighbouring joints)."""
    n = int(seconds * rate_hz)
    pose = np.array([300, -200, 500, 100, -400, 250])
    away = (np.arange(n) % 2)[:, None] * np.array([1, -1, 1, -1, 1, -1]) * amplitude
    return SimpleNamespace(t=(np.arange(n) + 0.5) / rate_hz,
                           theta=(pose + away) * ENCODER_COUNT_RAD)


def section_curves(design, args, out, unit, tmp) -> None:
    curved = with_example_curves(unit["calibration"])
    paths = {"without curves": unit["path"],
             "with both curves": C.save(curved, tmp / "curved-unit.toml")}
    check = twin.simulate(duration_s=6, rate_hz=200, **twin.same_unit(unit["truth"], 3))
    lines = ["### curve tables on the ATmega328P (the paper unit's calibration)", "",
             "| calibration | flash | static RAM | avrxmega3 check flash | solve cycles mean "
             "(max) | whole sample mean | CPU at 200 Hz |", "|---|---|---|---|---|---|---|"]
    rows = {}
    for label, path in paths.items():
        image = design_firmware(Path(DEFAULT_DESIGN), path)
        probe = appbuild.size_check_app("avrxmega3", image.elf.parent.parent / "include",
                                        name=f"probe-{label.split()[0]}")
        t = stream_log(image, check, rate_hz=200, hold_s=1.0).stats["timing"]
        rows[label] = {"flash": image.sizes.flash, "ram": image.sizes.ram,
                       "avrxmega3_flash": probe.sizes.flash, "timing": t}
        lines.append(f"| {label} | {image.sizes.flash} | {image.sizes.ram} | "
                     f"{probe.sizes.flash} | {t['solve_cycles']['mean']:.0f} "
                     f"({t['solve_cycles']['max']:.0f}) | {t['process_cycles']['mean']:.0f} | "
                     f"{100 * t['cpu_busy']:.0f} % (missed {t['missed_ticks']}) |")
    print("\n".join(lines) + "\n", flush=True)
    out["curves"] = rows
    lines = ["### the worst case: every joint moving and reversing every sample", "",
             "| calibration | rate | counts alternating by | solve cycles mean (max) | "
             "whole sample mean | CPU | missed |", "|---|---|---|---|---|---|---|"]
    worst = []
    for label, path in paths.items():
        # Built to accept rates beyond its rating (as tools/bench_virtual_board.py does).
        image = design_firmware(Path(DEFAULT_DESIGN), path, defines=UNRATED)
        for rate in WORST_RATES_HZ:
            for amplitude in WORST_AMPLITUDES:
                t = stream_log(image, alternating_counts(rate, amplitude), rate_hz=rate,
                               hold_s=1.0).stats["timing"]
                worst.append({"calibration": label, "rate_hz": rate, "amplitude": amplitude,
                              "timing": t})
                lines.append(f"| {label} | {rate} Hz | {amplitude} | "
                             f"{t['solve_cycles']['mean']:.0f} ({t['solve_cycles']['max']:.0f}) "
                             f"| {t['process_cycles']['mean']:.0f} | {100 * t['cpu_busy']:.1f} % "
                             f"| {t['missed_ticks']} of {t['solve_cycles']['n']} |")
                print(lines[-1], file=sys.stderr, flush=True)
    print("\n".join(lines) + "\n", flush=True)
    out["curves_worst"] = worst


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="600 s calibration runs, 120 s evaluation, 60 s on the board")
    parser.add_argument("--sections", default="paper,board,sizes,effects")
    parser.add_argument("--board-rate", type=int, default=250,
                        help="the calibrated board's stream rate (default 250 Hz, its highest)")
    parser.add_argument("--board-seconds", type=float, default=None,
                        help="seconds of the evaluation run streamed by the board (default all)")
    parser.add_argument("--sweep", default="250,275,300",
                        help="rates (Hz) of the short overrun check")
    parser.add_argument("--rig-latency", type=float, default=None, metavar="SECONDS",
                        help="the paper unit's calibration states the rig's latency instead of "
                             "fitting it (delta6 calibrate --rig-latency; the twin's rig: 0.01)")
    parser.add_argument("--effects", default="",
                        help="comma-separated effects of the effects section (default all)")
    parser.add_argument("--effect-seeds", type=int, default=1, metavar="N",
                        help="the effects section on seeds 1..N (calibration run on seed s, "
                             "unseen run on s + 1)")
    parser.add_argument("--json", metavar="OUT.json")
    args = parser.parse_args(argv)
    args.cal_duration = 600.0 if args.quick else 2000.0
    args.eval_duration = 120.0 if args.quick else 600.0
    if args.quick and args.board_seconds is None:
        args.board_seconds = 60.0
    args.sweep = [int(v) for v in args.sweep.split(",") if v]
    args.effects = [v for v in args.effects.split(",") if v]
    sections = set(args.sections.split(","))
    design = load_checked(DEFAULT_DESIGN)
    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="delta6-bench-calibration-") as tmp:
        tmp = Path(tmp)
        unit = None
        if sections & {"paper", "board", "sizes", "curves"}:
            unit = section_paper(design, args, out, tmp)
        if "sizes" in sections:
            section_sizes(design, args, out, unit)
        if "board" in sections:
            section_board(design, args, out, unit)
        if "curves" in sections:
            section_curves(design, args, out, unit, tmp)
        if "effects" in sections:
            section_effects(design, args, out, tmp)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
