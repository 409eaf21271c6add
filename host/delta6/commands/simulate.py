"""``delta6 simulate``: a simulated calibration run of the digital twin, as a log and its truth."""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from delta6.core import accuracy
from delta6.core import design as design_mod
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.outputs import check_not_an_input, check_output_file
from delta6.core.spec import full_scale
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import MAX_FULL_SCALES, MAX_SAMPLE_STEP_S
from delta6.twin import (
    EFFECT_NAMES,
    REGISTRY,
    SCENARIOS,
    build_effects,
    parse_request,
    random_effect,
    simulate,
    write_log,
)
from delta6.twin.scenarios import SCENARIO_HELP, refuse_repeats
from delta6.twin.truth import read_truth, same_unit, truth_path

NAME = "simulate"
HELP = "simulate a calibration run (digital twin): a log of encoder angles and reference wrench"
DEFAULT_DESIGN = design_mod.DEFAULT_DESIGN
#: The slowest log the readers (evaluate, diagnose, calibrate, train) accept as seconds.
LEAST_RATE_HZ = 1.0 / MAX_SAMPLE_STEP_S


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="log to write; the truth goes to OUT.truth.json next to it")
    parser.add_argument("--scenario", metavar="NAME",
                        help="ideal, paper, or one effect's name (see --list); default ideal")
    parser.add_argument("--effect", action="append", default=[], metavar="SPEC",
                        help="add an effect: NAME[:key=value,...], e.g. backlash or "
                             "joint_friction:coulomb_nm=0.01,formulation=lugre (repeatable)")
    parser.add_argument("--magnitude", metavar="M",
                        help="strength of drawn effects, 0..1 across the realistic range "
                             "(default 0.5)")
    parser.add_argument("--random", action="store_true",
                        help="draw each --effect's formulation and magnitude from the seed")
    parser.add_argument("--seed", default="0", metavar="N", help="random seed (default 0)")
    parser.add_argument("--duration", default="2000", metavar="S",
                        help="seconds of log (default 2000, the paper's run)")
    parser.add_argument("--rate", default="50", metavar="HZ", help="samples per second (50)")
    parser.add_argument("--design", default=None, metavar="DESIGN.toml",
                        help="design file (default designs/delta6.toml)")
    parser.add_argument("--record-temp", action="store_true",
                        help="write temp_c even without thermal_drift (so that the column's "
                             "presence reveals nothing)")
    parser.add_argument("--unit", metavar="RUN.truth.json",
                        help="simulate the same unit as a previous run (its design, effects and "
                             "parameters, the same rig) with a new trajectory, noise and "
                             "temperature history drawn from --seed")
    parser.add_argument("--force", action="store_true",
                        help="replace an existing OUT.csv and its truth file (refused "
                             "otherwise: a rig log of that name is not regenerable)")
    parser.add_argument("--list", action="store_true",
                        help="list the effects (parameters, units, realistic ranges) and "
                             "scenarios, then exit")


def _number(text: str, what: str, *, low: float, integer: bool = False,
            high: float = math.inf) -> float:
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        kind = "a whole number" if integer else "a number"
        raise UserError(f"{what} takes {kind}, got {text!r}") from None
    if not math.isfinite(value):
        raise UserError(f"{what} must be a finite number, got {text}")
    if not low <= value <= high:
        bounds = f">= {low:g}" if high == math.inf else f"in [{low:g}, {high:g}]"
        raise UserError(f"{what} must be {bounds}, got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    if args.list:
        print(listing())
        return 0
    if not args.output:
        raise UserError("missing -o OUT.csv (the log to write)")
    seed = int(_number(args.seed, "--seed", low=0, integer=True))
    duration = _number(args.duration, "--duration", low=0.0)
    rate = _number(args.rate, "--rate", low=0.0, high=10_000.0)
    if rate < LEAST_RATE_HZ:
        raise UserError(f"--rate must be at least {LEAST_RATE_HZ:g} Hz, got {args.rate}: the "
                        "log readers take a slower log's time for milliseconds")
    magnitude = (None if args.magnitude is None
                 else _number(args.magnitude, "--magnitude", low=0.0, high=1.0))
    out = Path(args.output)
    # The run of the same unit again must not replace the run (or the truth) it came from.
    inputs = [args.unit, args.design]
    check_not_an_input(out, "-o", inputs)
    try:
        check_not_an_input(truth_path(out), "-o", inputs)
    except UserError:
        raise UserError(f"-o {out}: its truth file {truth_path(out)} would replace the --unit "
                        "file it comes from; name the new run differently") from None
    # A log of that name may be a rig's: not regenerable, so replaced only when asked.
    for path in (out, truth_path(out)):
        check_output_file(path, "-o", force=args.force)
    if args.unit:
        kwargs = _unit(args, seed, magnitude)
        if args.record_temp:
            kwargs["record_temp"] = True
    else:
        kwargs = {"design": load_checked(args.design or DEFAULT_DESIGN),
                  "effects": _effects(args, seed, magnitude), "seed": seed,
                  "record_temp": True if args.record_temp else None,
                  "scenario": args.scenario}
    effects = kwargs["effects"]

    progress = Progress(sys.stderr, enabled=duration * rate >= 20_000)
    started = time.perf_counter()
    try:
        result = simulate(duration_s=duration, rate_hz=rate, progress=progress.stage, **kwargs)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    simulated = time.perf_counter() - started
    log_path, truth_file = write_log(result, out, progress=lambda f: progress.stage("write", f))
    progress.done()
    written = time.perf_counter() - started - simulated
    print(summary(result, effects, log_path, truth_file, simulated, written))
    return 0


def _unit(args, seed: int, magnitude: float | None) -> dict:
    """``simulate`` arguments for the unit of a previous run (``--unit``)."""
    given = [flag for flag, on in (("--scenario", args.scenario), ("--effect", args.effect),
                                   ("--random", args.random),
                                   ("--magnitude", magnitude is not None)) if on]
    if given:
        raise UserError(f"--unit takes the effects of the recorded run; drop {given[0]}")
    truth = read_truth(args.unit)
    try:
        kwargs = same_unit(truth, seed)
    except UserError as exc:    # a hand-edited truth file: name it
        raise UserError(f"{args.unit}: {exc}") from None
    if args.design:
        design = load_checked(args.design)
        if design.hash32() != kwargs["design"].hash32():
            raise UserError(f"{args.unit} was simulated with design "
                            f"'{kwargs['design'].name}' (hash 0x{kwargs['design'].hash32():08x}),"
                            f" not {args.design}")
    return kwargs


def _effects(args, seed: int, magnitude: float | None):
    name = args.scenario or "ideal"
    if name not in SCENARIOS:
        raise UserError(f"unknown scenario {name!r} (one of {', '.join(SCENARIOS)})")
    fixed = list(SCENARIOS[name])
    if magnitude is not None and fixed and all(r.params for r in fixed):
        raise UserError(f"--magnitude does not apply to scenario {name}: its parameters are fixed")
    extra = [parse_request(spec) for spec in args.effect]
    if not args.random:
        return build_effects(fixed + extra, seed, magnitude)
    if not extra:
        raise UserError("--random draws the --effect entries; give at least one --effect")
    if magnitude is not None:
        raise UserError("--random draws the magnitudes; drop --magnitude")
    for r in extra:
        if r.params or r.formulation or r.magnitude is not None or r.joints:
            raise UserError(f"--random draws {r.name} entirely; give it without settings")
    refuse_repeats(fixed + extra)
    return build_effects(fixed, seed) + [random_effect(r.name, seed) for r in extra]


class Progress:
    """One self-overwriting status line on a terminal; silent otherwise or for short runs."""

    def __init__(self, stream, enabled: bool = True):
        self.stream = stream
        self.enabled = enabled and stream.isatty()
        self.last = -1.0

    def stage(self, stage: str, fraction: float) -> None:
        if not self.enabled or (0 < fraction < 1 and fraction - self.last < 0.02):
            return
        self.last = fraction if fraction < 1 else -1.0
        self.stream.write(f"\rsimulate: {stage:<12} {100 * fraction:5.1f} %")
        self.stream.flush()

    def done(self) -> None:
        if self.enabled:
            self.stream.write("\r" + " " * 40 + "\r")
            self.stream.flush()


def _short(values) -> str:
    values = np.atleast_1d(np.asarray(values, dtype=float))
    if np.all(values == values[0]):
        return f"{values[0]:.3g}"
    return "/".join(f"{v:.3g}" for v in values)


def describe(effect) -> str:
    params = ", ".join(f"{k} {_short(v)}" for k, v in effect.params.items())
    return f"{effect.NAME} ({effect.formulation}, acts on {'+'.join(s.value for s in effect.ACTS_ON)}): {params}"


def summary(result, effects, log_path: Path, truth_file: Path, simulated: float,
            written: float) -> str:
    truth = result.truth
    n = len(result)
    lines = [
        f"wrote {log_path} ({n} samples, {truth['duration_s']:g} s at {truth['rate_hz']:g} Hz"
        f"{', with temp_c' if result.temp_c is not None else ''}) and {truth_file.name}",
        f"design {truth['design']['name']} ({truth['design']['hash']}), scenario "
        f"{truth['scenario'] or '-'}, seed {truth['seed']}",
        "effects:" if truth["effects"] else "effects: none (ideal plant; noise and quantization only)",
    ]
    lines += [f"  {describe(e)}" for e in effects]
    table = {k: v for k, v in truth["analytical_error_pct_fs"].items() if k != "p100"}
    lines.append("analytical model vs reference (percent of full scale):")
    lines.append(accuracy.format_table(table, title=""))
    note = beyond_the_readers(result)
    if note:
        lines.append(note)
    lines.append(f"generated in {simulated:.2f} s, written in {written:.2f} s")
    return "\n".join(lines)


def beyond_the_readers(result) -> str | None:
    """A note when the reference leaves the range evaluate, diagnose, calibrate and train
    accept: the effects' magnitudes are absolute (friction in N*m, a harness in N), so on a
    design with soft springs or short links they can outgrow its full scale."""
    fs = full_scale(result.design)
    over = np.abs(result.wrench) > MAX_FULL_SCALES * fs
    if not over.any():
        return None
    axis = int(np.argmax(over.sum(axis=0)))
    return (f"note: {over.any(axis=1).mean():.0%} of the samples have a reference beyond "
            f"{MAX_FULL_SCALES:g}x the design's full scale (most on {AXES[axis]}): evaluate, "
            "diagnose, calibrate and train refuse such a log; the effects are sized for the "
            "shipped designs (a smaller --magnitude, or stiffer springs)")


def listing() -> str:
    lines = ["effects (magnitude 0..1 spans each primary parameter's realistic range, log scale):"]
    for name in EFFECT_NAMES:
        cls = REGISTRY[name]
        lines.append(f"  {name}  acts on {'+'.join(s.value for s in cls.ACTS_ON)}; "
                     f"formulations: {', '.join(cls.FORMULATIONS)}")
        for s in cls.SPECS:
            where = "" if s.formulations is None else f" [{', '.join(s.formulations)}]"
            kind = "" if s.primary else " (shape)"
            if s.low == s.high:
                rng = f"{s.low:g}"
            elif s.sign == "-":
                rng = f"{-s.high:g}..{-s.low:g}"
            else:
                rng = ("+-" if s.sign == "+-" else "") + f"{s.low:g}..{s.high:g}"
            lines.append(f"      {s.name:<26} {s.unit:<10} {s.shape:<6} {rng}{kind}{where}")
    lines.append("scenarios:")
    lines += [f"  {k:<20} {v}" for k, v in SCENARIO_HELP.items()]
    lines.append(f"truth file: OUT.csv -> {truth_path('OUT.csv').name}")
    return "\n".join(lines)
