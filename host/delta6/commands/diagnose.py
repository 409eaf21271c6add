"""``delta6 diagnose``: where the sim-to-real gap lies, which effect causes it, how far it
shrinks."""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from delta6.commands._port import number
from delta6.core.design import load, shipped_design, shipped_design_named
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.outputs import check_output_file, check_output_folder
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import (
    GapData,
    check_motion,
    errors_naming,
    frozen_stretches,
)
from delta6.diagnosis.report import verdict_lines, write_report
from delta6.diagnosis.run import diagnose_data
from delta6.link.logdata import wrench_from_device
from delta6.link.logfile import LogData, read_log

NAME = "diagnose"
HELP = "diagnose the gap between the analytical model and a log of reference wrenches"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="log with t, theta_e1..6, Fx..Mz "
                        "(docs/log-format.md); temp_c optional")
    parser.add_argument("--design", metavar="DESIGN.toml",
                        help="the design the log was recorded with (default: the shipped "
                             "design the log's header names by its hash, else designs/delta6.toml)")
    parser.add_argument("--force", action="store_true",
                        help="diagnose even when --design is not the design the log names")
    parser.add_argument("--json", metavar="OUT.json", help="write the full result as JSON")
    parser.add_argument("--report", metavar="OUT_DIR",
                        help="write a Markdown report with plots into this directory")
    parser.add_argument("--seed", type=number("--seed", int, 0), default=0, metavar="N",
                        help="seed of the block bootstrap (default 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")


def run(args: argparse.Namespace) -> int:
    if args.json:
        check_output_file(args.json, "--json", inputs=[args.log, args.design])
    if args.report:
        check_output_folder(args.report, "--report")
    log = read_log(args.log)
    refuse_device_log(log, args.log)
    design = load_checked(choose_design(log, args.log, args.design, args.force))
    check_motion(log.theta, str(args.log), why="the diagnosis cannot tell what a joint it "
                                               "never saw move does")

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"  {message}", file=sys.stderr, flush=True)

    with errors_naming(args.log):
        data = GapData.from_log(log, design)              # (the log's checks first)
        for note in frozen_stretches(log.t, log.theta):
            print(note, file=sys.stderr)
        del log                                           # the log's table is freed here
        result = json_safe(diagnose_data(data, seed=args.seed, progress=progress))
    if args.json:
        try:
            Path(args.json).write_text(json.dumps(result, indent=1, allow_nan=False))
        except OSError as exc:
            raise UserError(f"cannot write {args.json}: {exc.strerror}") from None
    if args.report:
        path = write_report(result, data, args.report, source=str(args.log))
        progress(f"report: {path}")
    print(summary(result))
    return 0


def refuse_device_log(log: LogData, name) -> None:
    """A device log's wrench is the device's own model output: diagnosing it compares the
    model with itself."""
    if wrench_from_device(log.meta):
        raise UserError(f"{name}: the wrench in this log is the device's own model output "
                        "(a device log), not a reference sensor's: the diagnosis compares the "
                        "model with a reference (docs/diagnosis.md)")


def choose_design(log: LogData, name, given: str | None, force: bool):
    """The design file to diagnose with: ``given`` if it is the one the log names (or
    ``force``), else the shipped design with the log's hash (or, without one, its name),
    else the default."""
    recorded = log.meta.get("design_hash")
    try:
        recorded = int(recorded, 16) if recorded else None
    except ValueError:
        raise UserError(f"{name}: design_hash {recorded!r} in the header is not a hex "
                        "number") from None
    label = f"design '{log.meta.get('design', '?')}' (hash 0x{recorded or 0:08x})"
    called = log.meta.get("design") or None
    if given is not None:
        if force:
            return given
        design = load(given)
        if recorded is not None and design.hash32() != recorded:
            raise UserError(f"{name} was recorded with {label}, but {given} has hash "
                            f"0x{design.hash32():08x}: pass the log's design, or --force "
                            "to diagnose against this one")
        if recorded is None and called and design.name != called:
            raise UserError(f"{name} names design '{called}' in its header, but {given} is "
                            f"'{design.name}': pass the log's design, or --force to "
                            "diagnose against this one")
        return given
    if recorded is None:
        # A header may name its design without the hash (a rig's, a simulator's).
        if called is None or load(DEFAULT_DESIGN).name == called:
            return DEFAULT_DESIGN
        path = shipped_design_named(called)
        if path is None:
            raise UserError(f"{name} names design '{called}' in its header, which is not a "
                            "shipped design: pass its file with --design")
        return path
    path = shipped_design(recorded)
    if path is None:
        raise UserError(f"{name} was recorded with {label}, which is not a shipped design: "
                        "pass its file with --design")
    return path


def json_safe(value):
    """The result with every non-finite number as null: JSON has no NaN (and strict readers
    refuse it)."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def summary(result: dict) -> str:
    def cell(v, width=8):
        return f"{v:>{width}.2f}" if v is not None else f"{'-':>{width}}"

    def row(label, values):
        return f"  {label:<28}" + "".join(cell(v) for v in values)

    lines = [f"Diagnosis of {result['samples']} samples ({result['seconds']:.1f} s); "
             "held-out p99 error, % FS:",
             f"  {'':<28}" + "".join(f"{a:>8}" for a in AXES),
             row("analytical model", result["baseline_heldout_p99_pct"])]
    for step in result["ladder"]:
        lines.append(row(f"+ {step['added']}", step["heldout_p99_pct"]))
    on_chip = result.get("on_chip") or {}
    if on_chip.get("heldout_p99_pct") is not None and on_chip["families"]:
        # The final model as a board applies it (causal features, applied families): a
        # forecast of what `delta6 calibrate` leaves on a run like this one.
        lines.append(row("on the chip (calibrate)", on_chip["heldout_p99_pct"]))
    play = (result.get("beyond_encoders") or {}).get("backlash")
    if play is not None:
        # Beyond any model on the encoders: the unit with its backlash's play taken away.
        lines.append(row("without the play (hardware)", play["heldout_p99_pct"]))
    if result["present"]:
        lines.append("Present (strongest first): " + ", ".join(result["present"]))
    elif not result["groups"]:
        lines.append("No significant unmodelled effect.")
    lines += [line[2:].replace("**", "") for line in verdict_lines(result)]
    top = ", ".join(f"{c['name']} {c['score']:.3f}" if c["score"] is not None
                    else f"{c['name']} -" for c in result["candidates"][:4])
    lines.append(f"Best candidates alone (share of held-out error removed): {top}")
    lines += [f"Warning: {w}" for w in result.get("warnings", [])]
    return "\n".join(lines)
