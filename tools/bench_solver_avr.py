#!/usr/bin/env python3
"""AVR cycle budget of the wrench solver: build the ATmega328P benchmark image, run it in
simavr, and report cycles per solve, time at 16 MHz, flash and RAM, the avrxmega3 size check
and the worst error of what the AVR computed against the Python reference (% full scale).

    .venv/bin/python tools/bench_solver_avr.py                      # designs/delta6.toml
    .venv/bin/python tools/bench_solver_avr.py designs/*.toml       # every variant
    .venv/bin/python tools/bench_solver_avr.py --solves 2000 --csv build/bench.csv
    .venv/bin/python tools/bench_solver_avr.py --stages             # + cycles per stage
    .venv/bin/python tools/bench_solver_avr.py --calibration unit.toml --stages
                                  # the calibrated solver of a unit (delta6 calibrate)

Exit status 1 if a requirement fails (more than 40,000 cycles per solve, an AVR result off by
more than the required accuracy, solverbench.REQUIRED_ACCURACY_PCT_FS % FS, or a solve that did
not succeed inside the box); 2 on bad input.
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from delta6.build import avrbuild
from delta6.commands.codegen import build_name, calibration_text
from delta6.core.calibrated import CalibratedModel
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.core.model import AXES, ENCODER_COUNT_RAD, wrench
from delta6.core.spec import full_scale
from delta6.sim import solverbench
from delta6_codegen import render, render_calibration

ROOT = Path(__file__).resolve().parents[1]


F_CPU = avrbuild.NANO.f_cpu
REQUIRED_CYCLES = 40_000
GOAL_CYCLES = 16_000
REQUIRED_ACCURACY_PCT_FS = solverbench.REQUIRED_ACCURACY_PCT_FS


def say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def label_of(path: Path) -> str:
    resolved = path.resolve()
    return resolved.relative_to(ROOT).as_posix() if resolved.is_relative_to(ROOT) else path.name


def include_dir_for(path: Path, design) -> Path:
    """The committed header for the baseline, a generated one under build/ for the others."""
    committed = avrbuild.COMMITTED_DESIGN_INCLUDE
    text = render(design, label_of(path))
    if (committed / "generated" / "delta6_design.h").read_text() == text:
        return committed
    include = avrbuild.design_include_dir(design.name)
    header = include / "generated" / "delta6_design.h"
    header.parent.mkdir(parents=True, exist_ok=True)
    if not header.exists() or header.read_text() != text:
        header.write_text(text)
    return include


def bench_one(path: Path, solves: int, csv_rows: list | None, stages: bool = False) -> bool:
    design = load(path)
    include = include_dir_for(path, design)
    say(f"[{design.name}] building the ATmega328P image and running {solves} solves in simavr ...")
    run = solverbench.run_bench(include, solves=solves, name=f"bench-{design.name}")
    rep = run.report
    ok = rep.status == 0
    ref = wrench(design, rep.delta * ENCODER_COUNT_RAD)
    fs = full_scale(design)
    err_pct = (np.abs(rep.wrench.astype(float) - ref) / fs).max(axis=0) * 100 if ok.any() else \
        np.full(6, np.nan)
    cyc = run.cycles
    say(f"[{design.name}] size checks (bare solver for atmega328p and avrxmega3) ...")
    probe_328 = solverbench.build_probe(include, "atmega328p")
    probe_x3 = solverbench.build_probe(include, "avrxmega3")
    img = run.image.sizes
    lim = int(np.abs(rep.delta).max())
    n_random = max(0, solves - 65)

    cycles_ok = cyc.max() <= REQUIRED_CYCLES
    accuracy_ok = bool(np.all(err_pct <= REQUIRED_ACCURACY_PCT_FS))
    status_ok = bool(ok.all())
    verdict = lambda good: "PASS" if good else "FAIL"  # noqa: E731
    us = cyc / (F_CPU / 1e6)
    lines = [
        f"Delta6 wrench solver on the ATmega328P at 16 MHz (simavr), design '{rep.design_name}' "
        f"({label_of(path)}, hash 0x{rep.design_hash:08x})",
        f"  inputs        {solves} solves: rest, the 64 corners of the joint box, {n_random} "
        f"random points (|delta| <= {lim} counts)",
        f"  status        {int(ok.sum())} OK, {int((~ok).sum())} failed   [{verdict(status_ok)}]",
        f"  cycles/solve  mean {cyc.mean():,.0f}  min {cyc.min():,}  max {cyc.max():,}"
        "   (the GPIOR0 marker overhead removed)",
        f"  time/solve    mean {us.mean():,.0f} us  max {us.max():,.0f} us at 16 MHz"
        f"  ->  {F_CPU / cyc.max():,.0f} solves/s worst case",
        f"  budget        required <= {REQUIRED_CYCLES:,} cycles: {verdict(cycles_ok)} "
        f"(max is {100 * cyc.max() / REQUIRED_CYCLES:.0f} % of it); goal {GOAL_CYCLES:,}: "
        + ("reached" if cyc.max() <= GOAL_CYCLES else
           f"not reached (mean x{cyc.mean() / GOAL_CYCLES:.2f})"),
        "  accuracy      worst |AVR - reference| per axis, % of full scale "
        f"(required <= {REQUIRED_ACCURACY_PCT_FS}): {verdict(accuracy_ok)}",
        "                " + "  ".join(f"{a} {e:.2e}" for a, e in zip(AXES, err_pct)),
        f"  image         bench sketch + Arduino core: flash {img.flash:,} B of "
        f"{avrbuild.NANO.flash_bytes:,}, static RAM {img.ram:,} B of {avrbuild.NANO.ram_bytes:,}"
        f", peak stack {rep.peak_stack} B",
        f"  solver alone  bare main, no Arduino core: ATmega328P flash {probe_328.sizes.flash:,} B,"
        f" static RAM {probe_328.sizes.ram} B; avrxmega3 (ATmega4809 instruction set) flash "
        f"{probe_x3.sizes.flash:,} B, static RAM {probe_x3.sizes.ram} B",
    ]
    if stages:
        say(f"[{design.name}] profile build with stage markers ...")
        prof = solverbench.run_bench(include, solves=solves, name=f"bench-profile-{design.name}",
                                     profile=True)
        lines.append("  stages        mean cycles per stage (profile build: stage markers add "
                     "a few cycles each)")
        for label, spans in prof.stages.items():
            lines.append(f"                {spans.mean():8,.0f}  {label}")
    print("\n".join(lines), flush=True)
    if csv_rows is not None:
        for i in range(len(cyc)):
            csv_rows.append([design.name, *rep.delta[i], int(rep.status[i]), int(cyc[i]),
                             *rep.wrench[i], *ref[i]])
    return cycles_ok and accuracy_ok and status_ok


def bench_calibrated(path: Path, cal_path: Path, solves: int, stages: bool) -> bool:
    """The calibrated solver of the unit ``cal_path`` along the bench's random walk: cycles,
    the stage profile and the worst difference from the Python calibrated model."""
    design = load(path)
    cal, _ = calibration_text(design, path, cal_path)
    include = avrbuild.design_include_dir(f"bench-{build_name(design, cal)}")
    generated = include / "generated"
    generated.mkdir(parents=True, exist_ok=True)
    (generated / "delta6_design.h").write_text(render(design, label_of(path)))
    (generated / "delta6_calibration.h").write_text(
        render_calibration(design, cal, label_of(path), label_of(cal_path)))
    say(f"[{cal.name}] building the calibrated bench and running {solves} solves in simavr ...")
    run = solverbench.run_bench(include, solves=solves, name="bench-calibrated",
                                calibrated=True, profile=stages)
    rep = run.report
    ok = rep.status == 0
    python, _ = CalibratedModel(design, cal).run(rep.delta.astype(float),
                                                 solverbench.CALIBRATED_PERIOD_S)
    err = (np.abs(rep.wrench.astype(float) - python) / full_scale(design))[ok].max(axis=0) * 100
    cyc = run.cycles
    lines = [
        f"Calibrated solver on the ATmega328P at 16 MHz (simavr): unit '{cal.name}' "
        f"(0x{cal.hash32():08x}; {', '.join(cal.effects) or 'no effects'})",
        f"  inputs        {solves} solves along a random walk at "
        f"{1 / solverbench.CALIBRATED_PERIOD_S:.0f} Hz; {int(ok.sum())} OK",
        f"  cycles/solve  mean {cyc.mean():,.0f}  min {cyc.min():,}  max {cyc.max():,}"
        + ("   (profile build: stage markers included)" if stages else ""),
        "  accuracy      worst |AVR - Python calibrated model| per axis, % of full scale "
        f"(required <= {REQUIRED_ACCURACY_PCT_FS}): "
        + ("PASS" if np.all(err <= REQUIRED_ACCURACY_PCT_FS) else "FAIL"),
        "                " + "  ".join(f"{a} {e:.2e}" for a, e in zip(AXES, err)),
    ]
    if stages:
        lines.append("  stages        mean cycles per stage")
        for label, spans in run.stages.items():
            lines.append(f"                {spans.mean():8,.0f}  {label}")
    print("\n".join(lines), flush=True)
    return bool(ok.all() and np.all(err <= REQUIRED_ACCURACY_PCT_FS))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("designs", nargs="*", type=Path, metavar="DESIGN.toml",
                        default=[ROOT / "designs" / "delta6.toml"])
    parser.add_argument("--solves", type=int, default=512,
                        help="number of solves (>= 65: rest + 64 corners + random); default 512")
    parser.add_argument("--stages", action="store_true",
                        help="also build a profile image and print the cycles of each stage")
    parser.add_argument("--csv", type=Path, metavar="PATH",
                        help="also write every solve (inputs, status, cycles, AVR and reference "
                             "wrench) to a CSV file")
    parser.add_argument("--calibration", type=Path, metavar="CAL.toml",
                        help="bench the calibrated solver of this unit instead (one design)")
    args = parser.parse_args(argv)
    if not 65 <= args.solves <= 20000:
        parser.error("--solves must be between 65 and 20000")
    rows = [] if args.csv else None
    if args.calibration is not None:
        if len(args.designs) != 1 or args.csv:
            parser.error("--calibration takes one design and no --csv")
        try:
            return 0 if bench_calibrated(args.designs[0], args.calibration, args.solves,
                                         args.stages) else 1
        except UserError as exc:
            print(f"bench_solver_avr: error: {exc}", file=sys.stderr)
            return 2
    try:
        results = [bench_one(path, args.solves, rows, args.stages) for path in args.designs]
    except UserError as exc:
        print(f"bench_solver_avr: error: {exc}", file=sys.stderr)
        return 2
    if rows is not None:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with args.csv.open("w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["design", *(f"delta{j + 1}" for j in range(6)), "status", "cycles",
                          *(f"avr_{a}" for a in AXES), *(f"ref_{a}" for a in AXES)])
            out.writerows(rows)
        say(f"wrote {args.csv}")
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
