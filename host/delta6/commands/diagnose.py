"""``delta6 diagnose``: where the sim-to-real gap lies, which effect causes it, how far it
shrinks."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import GapData
from delta6.diagnosis.report import verdict_lines, write_report
from delta6.diagnosis.run import diagnose_data
from delta6.link.logfile import read_log

NAME = "diagnose"
HELP = "diagnose the gap between the analytical model and a log of reference wrenches"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="log with t, theta_e1..6, Fx..Mz "
                        "(docs/log-format.md); temp_c optional")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="the design the log was recorded with")
    parser.add_argument("--json", metavar="OUT.json", help="write the full result as JSON")
    parser.add_argument("--report", metavar="OUT_DIR",
                        help="write a Markdown report with plots into this directory")
    parser.add_argument("--seed", type=int, default=0, help="seed of the block bootstrap")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")


def run(args: argparse.Namespace) -> int:
    design = load_checked(args.design)

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"  {message}", file=sys.stderr, flush=True)

    data = GapData.from_log(read_log(args.log), design)   # the log's table is freed here
    result = diagnose_data(data, seed=args.seed, progress=progress)
    if args.json:
        try:
            Path(args.json).write_text(json.dumps(result, indent=1))
        except OSError as exc:
            raise UserError(f"cannot write {args.json}: {exc.strerror}") from None
    if args.report:
        path = write_report(result, data, args.report, source=str(args.log))
        progress(f"report: {path}")
    print(summary(result))
    return 0


def summary(result: dict) -> str:
    def row(label, values):
        return f"  {label:<28}" + "".join(f"{v:>8.2f}" for v in values)

    lines = [f"Diagnosis of {result['samples']} samples ({result['seconds']:.1f} s); "
             "held-out p99 error, % FS:",
             f"  {'':<28}" + "".join(f"{a:>8}" for a in AXES),
             row("analytical model", result["baseline_heldout_p99_pct"])]
    for step in result["ladder"]:
        lines.append(row(f"+ {step['added']}", step["heldout_p99_pct"]))
    if result["present"]:
        lines.append("Present (strongest first): " + ", ".join(result["present"]))
    elif not result["groups"]:
        lines.append("No significant unmodelled effect.")
    lines += [line[2:].replace("**", "") for line in verdict_lines(result)]
    top = ", ".join(f"{c['name']} {c['score']:.3f}" for c in result["candidates"][:4])
    lines.append(f"Best candidates alone (share of held-out error removed): {top}")
    return "\n".join(lines)
