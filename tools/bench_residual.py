#!/usr/bin/env python3
"""On-chip residual model benchmark: accuracy, AVR cycles, flash and RAM, and the loop rate.

    .venv/bin/python tools/bench_residual.py                      # train, then measure (~10 min)
    .venv/bin/python tools/bench_residual.py --model MODEL.json   # measure a trained model
    .venv/bin/python tools/bench_residual.py --quick              # short runs, a smoke test
    .venv/bin/python tools/bench_residual.py --calibration        # over the unit's calibration
    .venv/bin/python tools/bench_residual.py --calibration --effects backlash,joint_friction

1. The twin's `paper` scenario: a calibration run (2000 s, seed 1) and an evaluation run of the
   same unit (600 s, seed 2: the first run's effects and parameters from its truth, a new
   trajectory and noise).
2. `delta6 train --target mcu` on the calibration run (unless --model), over the base model:
   the analytical one, or with --calibration the unit's calibration fitted on the same run
   (`delta6 calibrate`; the firmware then runs the calibrated model and the residual over it).
3. Table V on the evaluation run (p95, p99, max of |error| in % FS per axis): the analytical
   model, the int8 residual over the base as the board computes it (the integer reference,
   equal to the AVR's integers: tests/sim/test_residual_avr.py), and the float network
   through its ONNX export and onnxruntime.
4. The engine on the emulated ATmega328P (firmware/bench/residual_bench.cpp): cycles per
   sample, its integers checked against the reference on the way.
5. The application with the model: flash and static RAM of the ATmega328P image and of the
   avrxmega3 size check (the Nano Every's instruction set), against the image without a model.
6. The virtual board running that application at 200 and 250 Hz: overruns and cycles.
7. The evaluation run streamed through that application on the virtual board at the log's
   rate (--board-seconds of it; 0 skips): Table V of the wrench the board sends.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from delta6 import twin
from delta6.build import appbuild, avrbuild
from delta6.core import accuracy, int8net, residualmodel
from delta6.core.design import load
from delta6.core.model import AXES
from delta6.core.spec import full_scale
from delta6.learning import mcu
from delta6.link.device import Device
from delta6.link.logfile import LogData
from delta6.sim import residualbench
from delta6.sim.virtualboard import (
    VirtualBoard,
    demo_trajectory,
    measure_stream,
    theta_to_counts,
    write_replay,
)
from delta6.twin import truth as truth_mod
from delta6_codegen import render, render_calibration, render_model

ROOT = Path(__file__).resolve().parents[1]
F_CPU = 16_000_000


def runs(design, train_s: float, eval_s: float):
    first = twin.simulate(design, twin.scenario_effects("paper", 1), train_s, seed=1,
                          scenario="paper")
    args = truth_mod.replay_arguments(first.truth)
    args.update(seed=2, duration_s=eval_s)
    return first, twin.simulate(**args)


def log_of(run) -> LogData:
    return LogData(t=run.t, theta=run.theta, wrench=run.wrench)


def table_v(design, model: residualmodel.ResidualModel, onnx_path: Path | None, log,
            cal=None) -> dict:
    fs = full_scale(design)
    base = mcu.AnalyticalBase(design) if cal is None else mcu.CalibratedBase(design, cal)
    w_base = base.predict(log)
    u, counts, valid = mcu.board_inputs(log, design, w_base, model.net.input_scale)
    correction, _ = int8net.run(model.net, u, counts, valid=valid)
    rows = {"analytical": mcu.AnalyticalBase(design).predict(log)}
    if cal is not None:
        rows["calibrated"] = w_base
    rows[f"{base.name} + int8 residual ({model.name})"] = int8net.apply_output(
        w_base, correction, model.net.output_step)
    if onnx_path is not None and onnx_path.exists():
        v = int8net.feature_values(model.net.features, u, counts, valid=valid)
        rows[f"{base.name} + float residual (onnxruntime)"] = (
            w_base + mcu.onnx_correction(onnx_path, v))
    return {name: accuracy.percentiles(w, log.wrench, fs, (95, 99, 100)) for name, w in rows.items()}


def print_table(tables: dict) -> None:
    print(f"  {'% FS':<46} {'':>5}" + "".join(f"{a:>7}" for a in AXES) + "   mean")
    for name, t in tables.items():
        for key, label in (("p95", "p95"), ("p99", "p99"), ("p100", "max")):
            row = t[key]
            print(f"  {name if key == 'p95' else '':<46} {label:>5}"
                  + "".join(f"{v:7.2f}" for v in row) + f" {np.mean(row):6.2f}")


def headers(tmp: Path, design, model, cal=None) -> Path:
    gen = tmp / "generated"
    gen.mkdir(parents=True, exist_ok=True)
    (gen / "delta6_design.h").write_text(render(design, "designs/delta6.toml"))
    if cal is not None:
        (gen / "delta6_calibration.h").write_text(
            render_calibration(design, cal, "designs/delta6.toml", "unit.toml"))
    if model is not None:
        (gen / "delta6_model.h").write_text(render_model(model, "designs/delta6.toml",
                                                         "model.json"))
    return tmp


def loop_check(image, rates, seconds: float) -> list[dict]:
    t, theta = demo_trajectory(duration_s=30.0, rate_hz=1000.0, amplitude=0.9)
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        replay = write_replay(Path(tmp) / "motion.d6rp", t, theta_to_counts(theta))
        with VirtualBoard(image=image, replay=replay, loop=True, live=True, speed=0) as board:
            with Device(board.port, timeout=2.0) as dev:
                for rate in rates:
                    stats, lost = measure_stream(board, dev, rate, seconds)
                    t_stats = stats["timing"]
                    dev.stop()
                    out.append({"rate": rate, "missed": t_stats["missed_ticks"],
                                "lost": lost,
                                "solve": t_stats["solve_cycles"]["mean"],
                                "process": t_stats["process_cycles"]["mean"],
                                "busy": t_stats["cpu_busy"]})
    return out


def streamed_table(image, run, design, model, cal, seconds):
    """The evaluation run replayed to the virtual board at the log's rate: Table V of the
    wrench records the board sends (paired with the log rows its encoders served)."""
    from delta6.evaluation.boardstream import stream_log
    rate = int(round(mcu.nominal_rate(run.t)))
    started = time.perf_counter()
    board = stream_log(image, run, rate_hz=rate, seconds=seconds)
    moving = board.rows >= 0
    ref = run.wrench[board.rows[moving]]
    fs = full_scale(design)
    base = "calibrated" if cal is not None else "analytical"
    tables = {f"{base} + int8 residual ({model.name}), board": accuracy.percentiles(
        board.wrench[moving], ref, fs, (95, 99, 100))}
    # The host's integer reference on the counts the board latched, for comparison.
    if cal is not None:
        from delta6.core.calibrated import CalibratedModel
        host_base = CalibratedModel(design, cal).run(board.delta, 1.0 / rate)[0]
    else:
        from delta6.core import model as reference_model
        from delta6.core.model import ENCODER_COUNT_RAD
        host_base = reference_model.wrench(design, board.delta * ENCODER_COUNT_RAD)
    net = model.net
    correction, _ = int8net.run(net, int8net.quantize_input(host_base, net.input_scale),
                                board.delta, stride=int8net.stride_for(net, rate))
    host = int8net.apply_output(host_base, correction, net.output_step)
    gap = float(np.max(np.abs(board.wrench[moving] - host[moving]) / fs * 100))
    tables[f"{base} + int8 residual, host on the board's counts"] = accuracy.percentiles(
        host[moving], ref, fs, (95, 99, 100))
    note = (f"largest |board - host| {gap:.4f} % FS; "
            f"{moving.sum():,} records at {rate} Hz in {time.perf_counter() - started:.0f} s, "
            f"{100 * board.matched:.1f} % with their row's counts, missed periods "
            f"{board.stats['timing']['missed_ticks']}")
    return tables, note


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", type=Path, help="a trained model file (default: train one)")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "residual",
                        help="where the trained model goes (default build/residual/)")
    parser.add_argument("--quick", action="store_true", help="short runs (smoke test)")
    parser.add_argument("--seconds", type=float, default=2.0, help="board seconds per rate")
    parser.add_argument("--calibration", action="store_true",
                        help="calibrate the unit on the calibration run and train (or check "
                             "--model) over the calibrated model")
    parser.add_argument("--board-seconds", type=float, default=None,
                        help="seconds of the evaluation run to stream through the virtual "
                             "board (default: all of it; --quick: 30; 0: skip)")
    parser.add_argument("--effects", help="with --calibration: the effects to calibrate, "
                        "comma-separated (default: what the diagnosis finds)")
    args = parser.parse_args()
    design = load(ROOT / "designs" / "delta6.toml")
    train_s, eval_s = (300.0, 120.0) if args.quick else (2000.0, 600.0)
    print(f"twin 'paper': calibration run {train_s:g} s (seed 1), evaluation run {eval_s:g} s "
          "of the same unit (seed 2)", flush=True)
    first, second = runs(design, train_s, eval_s)
    cal, base = None, mcu.AnalyticalBase(design)
    if args.calibration:
        from delta6.calibration import calibrate
        started = time.perf_counter()
        effects = args.effects.split(",") if args.effects else None
        cal = calibrate(log_of(first), design, effects=effects, name="paper-unit-cal",
                        source="twin paper seed 1").calibration
        base = mcu.CalibratedBase(design, cal)
        print(f"calibrated '{cal.name}' 0x{cal.hash32():08x} ({', '.join(cal.effects)}) in "
              f"{time.perf_counter() - started:.0f} s", flush=True)
    if args.model is None:
        args.out.mkdir(parents=True, exist_ok=True)
        settings = mcu.default_settings(base, epochs=3 if args.quick else 30)
        started = time.perf_counter()
        name = "paper-unit" if cal is None else "paper-unit-over-cal"
        result = mcu.train_mcu(log_of(first), design, base, name=name, settings=settings,
                               source="twin paper seed 1")
        model_path = residualmodel.save(result.model, args.out / f"{name}.json")
        onnx_path = mcu.export_onnx(result.float_net, model_path.with_suffix(".onnx"),
                                    {"delta6_model_hash": f"0x{result.model.hash32():08x}"})
        print(f"trained {model_path} in {time.perf_counter() - started:.0f} s "
              f"({result.model.net.macs} multiply-accumulates per sample)")
        model = result.model
    else:
        model = residualmodel.load(args.model)
        residualmodel.check_base(model, design, cal)
        onnx_path = args.model.with_suffix(".onnx")
    net = model.net
    print(f"model '{model.name}' 0x{model.hash32():08x}: features "
          + ", ".join(f"{f.kind}({f.param})" if f.param else f.kind for f in net.features)
          + "; layers " + " -> ".join(str(x) for x in [net.inputs] + [l.shape[0] for l in net.layers])
          + f"; {net.macs} MACs; trained at {net.rate_hz:g} Hz")

    print("\nTable V on the evaluation run (integer reference = the board's integers):")
    print_table(table_v(design, model, onnx_path, log_of(second), cal))

    with tempfile.TemporaryDirectory() as tmp:
        include = headers(Path(tmp), design, model, cal)
        bench = residualbench.run(include, samples=600, rate_hz=250)
        base, counts, valid = residualbench.stream(600)
        ref, _ = int8net.run(net, base, counts, stride=bench.stride, valid=valid)
        exact = np.array_equal(ref, bench.correction)
        print(f"\nATmega328P, 16 MHz (simavr): residual step {bench.cycles.mean():,.0f} cycles mean, "
              f"{bench.cycles.max():,} max ({bench.cycles.mean() / F_CPU * 1e6:,.0f} us); "
              f"integers equal to the reference: {exact}")
        plain = (appbuild.build_app() if cal is None else appbuild.build_app(
            headers(Path(tmp) / "plain", design, None, cal), name="delta6-app-cal-bench"))
        with_model = appbuild.build_app(include, name="delta6-app-residual-bench",
                                        defines=["DELTA6_MAX_RATE_HZ=2000"])
        plain_x3 = appbuild.size_check_app("avrxmega3", Path(tmp) / "plain" if cal is not None
                                           else None)
        model_x3 = appbuild.size_check_app("avrxmega3", include)
        print(f"flash / static RAM, ATmega328P image: {with_model.sizes.flash:,} / "
              f"{with_model.sizes.ram:,} B of {avrbuild.NANO.flash_bytes:,} / "
              f"{avrbuild.NANO.ram_bytes:,} (without model{' (calibrated)' if cal else ''} "
              f"{plain.sizes.flash:,} / "
              f"{plain.sizes.ram:,})" + avrbuild.flash_note(with_model.sizes.flash))
        print(f"flash / static RAM, avrxmega3 size check: {model_x3.sizes.flash:,} / "
              f"{model_x3.sizes.ram:,} B of 49,152 / 6,144 (without model"
              f"{' (calibrated)' if cal else ''} "
              f"{plain_x3.sizes.flash:,} / {plain_x3.sizes.ram:,})")
        rows = loop_check(with_model, (200, 250), args.seconds)
        board_seconds = (30.0 if args.quick else None) if args.board_seconds is None \
            else args.board_seconds
        streamed = (streamed_table(with_model, second, design, model, cal, board_seconds)
                    if board_seconds != 0 else None)
    print("\nvirtual board with the model (wrench stream):")
    ok = exact
    for r in rows:
        print(f"  {r['rate']} Hz: missed periods {r['missed']}, lost records {r['lost']}, "
              f"solve + residual {r['solve']:,.0f} cycles, work per sample {r['process']:,.0f} "
              f"cycles, CPU busy {r['busy']:.0%}")
        if r["rate"] == 200:
            ok &= r["missed"] == 0 and r["lost"] == 0
    print(f"requirement: >= 200 Hz with no overrun: {'met' if ok else 'NOT met'}")
    if streamed is not None:
        tables, note = streamed
        print(f"\nstreamed by the virtual board ({note}):")
        print_table(tables)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
